"""The life-cycle table: what each observation does in each phase."""

from __future__ import annotations

import pytest

from fleet.mission.lifecycle import TRANSITIONS, Observation, advance, holds_target
from fleet.mission.phase import Phase


def test_the_happy_path_goes_from_computing_to_reached() -> None:
    phase = Phase.IDLE
    for observation, expected in [
        (Observation.MISSION_STARTED, Phase.COMPUTING),
        (Observation.RESULT_PUBLISHED, Phase.WAITING),
        (Observation.ASSIGNED_TARGET, Phase.COMMITTED),
        (Observation.TRACK_ECHOED, Phase.FLYING),
        (Observation.WITHIN_RADIUS, Phase.REACHED),
    ]:
        phase = advance(phase, observation)
        assert phase == expected


def test_flying_needs_the_echo_and_reached_needs_the_radius() -> None:
    assert advance(Phase.WAITING, Observation.TRACK_ECHOED) == Phase.WAITING
    assert advance(Phase.IDLE, Observation.WITHIN_RADIUS) == Phase.IDLE
    assert advance(Phase.FLYING, Observation.LEFT_ROUTE) == Phase.PREEMPTED
    assert advance(Phase.COMMITTED, Observation.LEFT_ROUTE) == Phase.COMMITTED


@pytest.mark.parametrize("held", [Phase.COMMITTED, Phase.FLYING])
def test_a_held_target_is_preempted_by_the_operator_and_failed_by_a_lost_link(held: Phase) -> None:
    assert holds_target(held)
    assert advance(held, Observation.OPERATOR_COMMAND) == Phase.PREEMPTED
    assert advance(held, Observation.LINK_LOST) == Phase.FAILED
    assert advance(held, Observation.RELEASED) == Phase.IDLE


def test_a_re_plan_hands_an_idle_uav_a_target_but_never_a_finished_one() -> None:
    assert advance(Phase.IDLE, Observation.ASSIGNED_TARGET) == Phase.COMMITTED
    # A candidate that reached its orphan may be handed the next one (it flies it).
    assert advance(Phase.REACHED, Observation.ASSIGNED_TARGET) == Phase.COMMITTED
    for final in (Phase.PREEMPTED, Phase.FAILED, Phase.ABORTED):
        assert advance(final, Observation.ASSIGNED_TARGET) == final


def test_abort_wins_from_every_mission_phase_and_a_new_mission_restarts() -> None:
    for phase in set(Phase) - {Phase.OFF, Phase.LINK_LOST}:
        assert advance(phase, Observation.ABORTED) == Phase.ABORTED
        assert advance(phase, Observation.MISSION_STARTED) == Phase.COMPUTING


def test_off_and_link_lost_are_not_mission_phases() -> None:
    assert not any(phase in (Phase.OFF, Phase.LINK_LOST) for _, phase in TRANSITIONS)
    assert all(after not in (Phase.OFF, Phase.LINK_LOST) for after in TRANSITIONS.values())
