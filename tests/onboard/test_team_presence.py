"""The team's liveliness (onboard.team_presence): who is left out, who is released, when."""

from __future__ import annotations

from fleet.consensus.mission_round import ASK_GRACE_S
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.piccolo.waypoint import Waypoint
from onboard.core import (
    LIVELINESS_GRACE_S,
)
from onboard.team_presence import TeamPresence
from tests.onboard.core_harness import (
    TARGETS,
    TWO_TARGETS,
    commit_three_uav_team,
    make_core,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


def test_dead_teammate_is_left_out_and_deadline_commits() -> None:
    core, out = make_core(112)
    core.on_alive(74, True, 0.0)
    core.on_alive(75, True, 0.0)
    mission = MissionTargets(mission=6, team=(74, 75, 112), targets=TARGETS, deadline_s=5.0)
    core.on_targets(mission, 0.0)
    core.on_result(UavResult(6, 74, (10.0, 10.0, 10.0)), 0.5)
    core.tick(1.0)
    core.on_alive(75, False, 0.0)  # killed
    core.tick(1.1)
    assert out.assignment_fetches == [6]  # 74 may have committed with 75's result
    core.tick(1.1 + ASK_GRACE_S)
    (report,) = out.on(SPACE.mission_assignment(6, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


def test_an_idle_uav_flies_the_target_of_a_holder_lost_after_the_commitment() -> None:
    core, out = make_core(200, (30.0, 35.0))
    commit_three_uav_team(core)
    (first,) = out.on(SPACE.mission_assignment(3, 200))
    assert isinstance(first, AssignmentReport) and first.target is None and first.epoch == 0
    assert out.on(SPACE.mission_replan(3, 200)) == []  # teammates hear epoch 0 by query
    assert core.state(0.2).phase == Phase.IDLE
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_alive(112, False, 5.0)  # the holder of target 1 is killed
    second = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert out.on(SPACE.mission_replan(3, 200)) == [second]  # and re-plans live too
    assert isinstance(second, AssignmentReport)
    assert (second.target, second.epoch, second.released) == (1, 1, (112,))
    assert second.pairs == {74: 0, 200: 1}
    assert core.state(5.0).phase == Phase.COMMITTED
    (waypoint,) = [c for c in out.autopilot if isinstance(c, Waypoint)]
    assert (waypoint.lat, waypoint.lon) == (TWO_TARGETS[1].lat, TWO_TARGETS[1].lon)


def test_a_liveliness_blip_after_the_commitment_releases_nobody() -> None:
    # A router failover withdraws a teammate's token and declares it again at once.
    core, out = make_core(200, (30.0, 35.0), liveliness_grace_s=LIVELINESS_GRACE_S)
    commit_three_uav_team(core)
    core.on_alive(112, False, 5.0)
    core.tick(5.1)
    core.on_alive(112, True, 5.2)
    core.tick(5.0 + LIVELINESS_GRACE_S + 1.0)
    reports = out.on(SPACE.mission_assignment(3, 200))
    assert [r.epoch for r in reports] == [0]  # type: ignore[attr-defined]


def test_a_teammate_gone_past_the_grace_is_released_at_the_next_tick() -> None:
    core, out = make_core(200, (30.0, 35.0), liveliness_grace_s=LIVELINESS_GRACE_S)
    commit_three_uav_team(core)
    core.on_telemetry(sample_telemetry(), 5.0)
    core.on_alive(112, False, 5.0)
    core.tick(5.0 + LIVELINESS_GRACE_S / 2)
    assert out.on(SPACE.mission_assignment(3, 200))[-1].epoch == 0  # type: ignore[attr-defined]
    core.on_telemetry(sample_telemetry(), 5.0 + LIVELINESS_GRACE_S)
    core.tick(5.0 + LIVELINESS_GRACE_S)
    report = out.on(SPACE.mission_assignment(3, 200))[-1]
    assert isinstance(report, AssignmentReport)
    assert (report.target, report.epoch, report.released) == (1, 1, (112,))


def test_a_teammate_is_released_once_it_stayed_gone_past_the_grace() -> None:
    team = TeamPresence(112, grace_s=2.0)
    assert team.alive == {112}
    assert team.came(7) and not team.came(7)
    assert not team.went(112, 0.0, committed=True)  # this UAV never leaves its own team
    assert not team.went(7, 0.0, committed=False)  # before the commitment: left out only
    assert team.alive == {112} and team.gone_past_grace(10.0) == []
    team.came(7)
    assert team.went(7, 1.0, committed=True)
    assert team.gone_past_grace(2.9) == []
    assert team.gone_past_grace(3.0) == [7]
    assert team.gone_past_grace(4.0) == []  # given once


def test_in_the_secure_profile_a_ghost_token_is_not_waited_for() -> None:
    """Tokens of 74 and 75 in a team with 112, a deadline far off: 74 spoke for itself
    (its signed state answered), 75 never does (a ghost). 112 waits for 74's result only,
    then decides without 75 once its question to the team has had its grace."""
    core, out = make_core(112, vouch_teammates=True)
    core.on_alive(74, True, 0.0)
    core.on_alive(75, True, 0.0)
    assert core.awaits_word() == [74, 75]
    core.on_spoke(74, 0.1)
    assert core.awaits_word() == [75]
    mission = MissionTargets(mission=6, team=(74, 75, 112), targets=TARGETS, deadline_s=60.0)
    core.on_targets(mission, 0.2)
    core.tick(0.3)
    assert out.on(SPACE.mission_assignment(6, 112)) == []  # 74's result is awaited
    core.on_result(UavResult(6, 74, (10.0, 10.0, 10.0)), 0.5)
    core.tick(0.6)
    core.tick(0.6 + ASK_GRACE_S)
    (report,) = out.on(SPACE.mission_assignment(6, 112))
    assert isinstance(report, AssignmentReport) and report.team == (74, 112)


def test_a_token_counts_once_its_uav_spoke_and_needs_its_word_again_after_it_went() -> None:
    presence = TeamPresence(112, vouch=True)
    assert not presence.came(74) and presence.alive == {112}
    assert presence.spoke(74) and presence.alive == {74, 112}
    assert not presence.spoke(74)  # counted already
    assert presence.went(74, 1.0, committed=True)
    assert presence.gone_past_grace(1.0 + presence.grace_s) == [74]
    assert not presence.came(74), "a token declared again needs the UAV's word again"
    assert not presence.went(75, 2.0, committed=True), "a ghost's token going releases nobody"
    assert presence.spoke(74) and 74 in presence.alive
