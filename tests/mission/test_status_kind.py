"""Status kinds: each kind's severity (the one rule), and the message carrying it."""

from __future__ import annotations

import msgspec
import pytest

from fleet.mission.messages import StatusText
from fleet.mission.phase import Severity
from fleet.mission.status_kind import StatusKind
from fleet.payload.bodies import decode_status, status_kind_of_text

ERRORS = {
    StatusKind.ERROR,
    StatusKind.LINK_LOST,
    StatusKind.OPM_REFUSED,
    StatusKind.MISSION_REFUSED,
    StatusKind.CANNOT_FLY,
    StatusKind.ZONE_INCURSION,
}
WARNINGS = {
    StatusKind.WARNING,
    StatusKind.NOT_TAKING_PART,
    StatusKind.SOLVER_DEGRADED,
    StatusKind.DEADLINE_PASSED,
    StatusKind.ORPHAN_REFUSED,
    StatusKind.NOT_REACHED,
    StatusKind.TARGET_GIVEN_UP,
    StatusKind.STALE_TARGET_LEFT,
}


@pytest.mark.parametrize("kind", list(StatusKind))
def test_every_kind_has_its_severity(kind: StatusKind) -> None:
    expected = (
        Severity.ERROR
        if kind in ERRORS
        else Severity.WARNING
        if kind in WARNINGS
        else Severity.INFO
    )
    assert kind.severity is expected


def test_the_severity_on_the_wire_is_always_the_kind_s() -> None:
    status = StatusText("x", StatusKind.CANNOT_FLY, 3, 1, severity=Severity.INFO)
    assert status.severity is Severity.ERROR
    wire = msgspec.json.encode(status)
    assert msgspec.json.decode(wire) == {
        "text": "x",
        "kind": "cannot_fly",
        "mission": 3,
        "target": 1,
        "severity": "error",
    }
    lying = b'{"text": "x", "kind": "reached", "severity": "error"}'
    assert msgspec.json.decode(lying, type=StatusText).severity is Severity.INFO


def test_a_status_from_before_kinds_decodes_as_info() -> None:
    old = msgspec.json.decode(b'{"text": "reached target 0", "severity": "info"}', type=StatusText)
    assert (old.kind, old.mission, old.target) == (StatusKind.INFO, None, None)


@pytest.mark.parametrize(
    ("text", "kind"),
    [
        ("error: autopilot link lost", StatusKind.ERROR),
        ("warning: target not reached: x", StatusKind.WARNING),
        ("reached target 0 (12 m from it)", StatusKind.INFO),
        ("Warning, capitalised: no prefix", StatusKind.INFO),
        ("", StatusKind.INFO),
    ],
)
def test_the_payload_edge_maps_a_text_to_a_generic_kind(text: str, kind: StatusKind) -> None:
    assert status_kind_of_text(text) is kind
    assert decode_status(text.encode()) == StatusText(text, kind)
