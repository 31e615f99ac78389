"""Reporting status and state (onboard.state_report)."""

from __future__ import annotations

from fleet.mission.messages import StatusText
from fleet.mission.phase import Phase, Severity
from fleet.mission.status_kind import StatusKind
from onboard.core import (
    LINK_LOST_S,
)
from onboard.state_report import overall_phase
from tests.onboard.core_harness import TARGETS, fly_target_1, make_core, telemetry_at


def test_status_messages_carry_their_severity() -> None:
    core, out = make_core()
    core.tick(LINK_LOST_S + 1.0)
    severities = {m.text: m.severity for _, m in out.published if isinstance(m, StatusText)}
    assert Severity.ERROR in severities.values()


def test_status_messages_carry_their_kind_mission_and_target() -> None:
    core, out = make_core()
    fly_target_1(core, out)
    core.on_telemetry(telemetry_at(TARGETS[1].lat + 0.0005, TARGETS[1].lon), 59.0)
    said = [(m.kind, m.mission, m.target) for _, m in out.published if isinstance(m, StatusText)]
    assert said == [
        (StatusKind.COMPUTING, 1, None),
        (StatusKind.APPROACH_TIMES, 1, None),
        (StatusKind.TARGET_CHOSEN, 1, 1),
        (StatusKind.FLYING_TO_TARGET, 1, 1),
        (StatusKind.REACHED, 1, 1),
        (StatusKind.TARGET_CHOSEN, 1, 0),  # the next of its queue
    ]


def test_off_and_link_lost_outrank_the_missions_phase() -> None:
    mission = (Phase.FLYING, None)
    shown = overall_phase(enabled=False, silent_s=9.0, link_lost=True, mission=mission)
    assert shown[0] == Phase.OFF
    shown = overall_phase(enabled=True, silent_s=9.0, link_lost=True, mission=mission)
    assert shown == (Phase.LINK_LOST, "no telemetry from the autopilot for 9.0 s")
    # Never any telemetry: the mission's phase (the mission declines by itself).
    assert overall_phase(enabled=True, silent_s=None, link_lost=True, mission=mission) == mission
    assert overall_phase(enabled=True, silent_s=0.1, link_lost=False, mission=None) == (
        Phase.IDLE,
        None,
    )
