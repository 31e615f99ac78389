"""An assignment's pairs are keyed by Piccolo ID (int), on a wire that stays JSON strings."""

from __future__ import annotations

import msgspec
import pytest

from fleet.mission.messages import AssignmentReport

#: An assignment report as published before pairs were int-keyed.
OLD_STYLE = (
    b'{"mission":7,"uav":74,"target":0,"pairs":{"74":0,"112":1},"unassigned":[2],'
    b'"team":[74,112],"digest":"abc","eta_s":12.5,"epoch":0,"released":[]}'
)


def test_an_old_style_payload_decodes_to_int_keys_and_encodes_back_the_same() -> None:
    report = msgspec.json.decode(OLD_STYLE, type=AssignmentReport)
    assert report.pairs == {74: 0, 112: 1}
    assert all(type(uav) is int for uav in report.pairs)
    # Encoded back: the old fields as they were, then the queue fields' defaults.
    assert msgspec.json.encode(report).startswith(OLD_STYLE[:-1] + b",")
    assert report.queues == {} and report.objective == "greedy"
    # A recording's decoded JSON (string keys) converts the same way.
    assert msgspec.convert(msgspec.json.decode(OLD_STYLE), AssignmentReport, str_keys=True) == (
        report
    )


@pytest.mark.parametrize("key", ["abc", "074", "0", "65521", "-1", " 74", "74.0"])
def test_a_pair_that_is_no_piccolo_id_is_refused_on_decode(key: str) -> None:
    payload = OLD_STYLE.replace(b'"112":1', f'"{key}":1'.encode())
    with pytest.raises(msgspec.ValidationError):
        msgspec.json.decode(payload, type=AssignmentReport)
