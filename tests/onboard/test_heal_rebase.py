"""Two plans of one mission after a 2|2 split heals, as one UAV's module of the side
that committed on its own two results sees it: it re-bases onto the other side's plan,
built from all four results, gives its standing for that plan's re-plan, and adopts the
plan solved again with it counted in (fleet.consensus.heal)."""

from __future__ import annotations

import msgspec

from fleet.consensus.mission_round import MissionRound
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult
from onboard.core import OnboardCore
from tests.onboard.core_harness import TARGETS, Recorder, make_core, run_with_telemetry

SPACE = KeySpace()
TEAM = (101, 102, 103, 104)
OWN = (80.0, 40.0, 60.0)  # 101's scripted planner
TIMES = {101: OWN, 102: (20.0, 70.0, 90.0), 103: (90.0, 30.0, 15.0), 104: (60.0, 50.0, 25.0)}
MISSION = MissionTargets(mission=1, team=TEAM, targets=TARGETS, deadline_s=10.0)


def _weak_side() -> tuple[OnboardCore, Recorder]:
    """101 (this core) hears 102's result only: 103 and 104 are cut off. It waits out the
    deadline, asks the team, and commits on its own two."""
    core, out = make_core(uav=101, fresh_replans=True)
    core.on_alive(102, True, 0.0)
    core.on_targets(MISSION, 1.0)
    core.on_result(UavResult(1, 102, TIMES[102]), 1.05)
    run_with_telemetry(core, 1.05, 13.0)
    (report,) = out.on(SPACE.mission_assignment(1, 101))
    assert isinstance(report, AssignmentReport) and report.team == (101, 102)
    return core, out


def _strong_side() -> MissionRound:
    """103's round: committed on all four results, then 101 and 102 counted out (the cut)
    and back in (the heal); their standings never came: the epoch's append plan."""
    strong = MissionRound(MISSION, 103, started=1.0, resolving=True)
    for uav, times in TIMES.items():
        strong.add_result(UavResult(1, uav, times))
    strong.decide(set(TEAM))
    strong.release((101, 102))
    strong.replan(5.0)
    assert strong.expire(10.0) is not None
    strong.rejoin((101, 102))
    strong.replan(15.0)
    report = strong.expire(20.0)
    assert report is not None and report.epoch == 4 and report.basis is None
    return strong


def _standings(out: Recorder) -> list[UavResult]:
    key = SPACE.mission_result(1, 101)
    return [m for m in out.on(key) if isinstance(m, UavResult) and m.basis is not None]


def test_after_the_heal_the_side_with_fewer_results_rebases_and_the_team_has_one_plan() -> None:
    core, out = _weak_side()
    strong = _strong_side()
    theirs = strong.committed
    assert theirs is not None
    for uav in (103, 104):
        core.on_alive(uav, True, 14.0)
    core.on_assignment(theirs, 14.1)
    assert core.round is not None and core.round.committed is not None
    # On today's main the two plans stay apart: 101 keeps the one of two results.
    assert core.round.committed.digest == theirs.digest
    assert core.round.committed.queues == theirs.queues
    now = run_with_telemetry(core, 14.1, 15.0)
    (standing,) = _standings(out)  # for the winner's append plan: counted in there
    assert standing.basis == theirs.digest
    for uav in (102, 104):
        strong.add_standing(UavResult(1, uav, TIMES[uav], basis=theirs.digest))
    strong.add_standing(standing)
    assert strong.resolve_ready() is None  # 103's own still missing
    strong.add_standing(UavResult(1, 103, TIMES[103], basis=theirs.digest))
    resolved = strong.resolve_ready()
    assert resolved is not None
    core.on_assignment(resolved, now)
    assert core.round.committed.digest == resolved.digest
    # Its copy of the one plan is published for the ground and its teammates.
    (*_, last) = out.on(SPACE.mission_replan(1, 101))
    assert isinstance(last, AssignmentReport) and last.digest == resolved.digest


def test_the_side_with_more_results_ignores_the_other_sides_plan() -> None:
    core, out = make_core(uav=103, fresh_replans=True, times=TIMES[103])
    for uav in (101, 102, 104):
        core.on_alive(uav, True, 0.0)
    core.on_targets(MISSION, 1.0)
    for uav in (101, 102, 104):
        core.on_result(UavResult(1, uav, TIMES[uav]), 1.05)
    run_with_telemetry(core, 1.05, 2.0)
    (mine,) = out.on(SPACE.mission_assignment(1, 103))
    assert isinstance(mine, AssignmentReport) and mine.team == TEAM
    weak = MissionRound(MISSION, 101, started=1.0)
    for uav in (101, 102):
        weak.add_result(UavResult(1, uav, TIMES[uav]))
    theirs = weak.decide({101, 102})
    core.on_assignment(theirs, 3.0)
    core.on_assignment(msgspec.structs.replace(theirs, epoch=2), 3.1)
    assert core.round is not None and core.round.committed is not None
    assert core.round.committed.digest == mine.digest
    assert core.round.released == set() and out.outcome_fetches == []
