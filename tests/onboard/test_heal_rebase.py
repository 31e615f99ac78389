"""Two plans of one mission after a 2|2 split heals, as one UAV's module of the side
that committed on its own two results sees it: it re-bases onto the other side's plan,
built from all four results, gives its standing for that plan's re-plan, and adopts the
plan solved again with it counted in (fleet.consensus.heal)."""

from __future__ import annotations

import msgspec

from fleet.consensus.mission_round import MissionRound
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.core import TARGET_WAYPOINT, OnboardCore
from tests.onboard.core_harness import (
    TARGETS,
    Recorder,
    make_core,
    run_with_telemetry,
    telemetry_at,
)

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


# ---- a side re-based onto a plan built without it ---------------------------------------
PAIR = (101, 102)
PAIR_MISSION = MissionTargets(mission=2, team=PAIR, targets=TARGETS, deadline_s=10.0)


def _alone(uav: int) -> tuple[OnboardCore, Recorder]:
    """`uav` cut off from its teammate from the start (the results' fan-out lost): it
    commits on its own result alone, a plan of one UAV holding every target."""
    core, out = make_core(uav=uav, fresh_replans=True, times=TIMES[uav])
    core.on_targets(PAIR_MISSION, 1.0)
    run_with_telemetry(core, 1.0, 3.0)
    (report,) = out.on(SPACE.mission_assignment(2, uav))
    assert isinstance(report, AssignmentReport) and report.team == (uav,)
    assert sorted(report.queues[uav]) == [0, 1, 2]
    return core, out


class _Relay:
    """Carries what each core publishes to the others (results and standings, re-plans),
    as the bus does once the partition healed."""

    def __init__(self, cores: dict[int, tuple[OnboardCore, Recorder]]) -> None:
        self.cores = cores
        self.sent = {uav: len(out.published) for uav, (_, out) in cores.items()}

    def run(self, start: float, end: float) -> float:
        now = start
        while now < end:
            now += 0.25
            for uav, (_core, out) in self.cores.items():
                new, self.sent[uav] = out.published[self.sent[uav] :], len(out.published)
                for key, message in new:
                    for other, (peer, _) in self.cores.items():
                        if other == uav:
                            continue
                        if isinstance(message, UavResult):
                            peer.on_result(message, now)
                        elif isinstance(message, AssignmentReport) and "replan" in key:
                            peer.on_assignment(message, now)
            for core, _ in self.cores.values():
                run_with_telemetry(core, now - 0.25, now)
        return now


def test_a_uav_rebased_onto_a_plan_built_without_it_is_counted_in_and_flies() -> None:
    """Both UAVs committed alone; after the heal 102 re-bases onto 101's plan (the tie
    goes to the team that sorts first), in which it holds nothing. It stands for that
    plan, 101 counts it in as it counts in a UAV back from a loss, and the team solves
    what is left with both: 102 flies again, and the target it reached before the heal
    stays reached (planned for nobody)."""
    winner, won = _alone(101)
    loser, lost = _alone(102)
    # 102 reaches its first target (0) on its own plan before the heal.
    waypoint = lost.autopilot[-1]
    assert isinstance(waypoint, Waypoint)
    assert (waypoint.lat, waypoint.lon) == (TARGETS[0].lat, TARGETS[0].lon)
    loser.on_waypoint(waypoint, 3.5)
    loser.on_track(Track(TARGET_WAYPOINT), 3.6)
    loser.on_telemetry(telemetry_at(TARGETS[0].lat, TARGETS[0].lon), 4.0)
    assert loser.round is not None and loser.round.reached_targets == {0: 102}
    # The heal: each sees the other alive, and hears the other's plan (a catch-up).
    winner.on_alive(102, True, 5.0)
    loser.on_alive(101, True, 5.0)
    (theirs,) = won.on(SPACE.mission_assignment(2, 101))
    (ours,) = lost.on(SPACE.mission_assignment(2, 102))
    assert isinstance(theirs, AssignmentReport) and isinstance(ours, AssignmentReport)
    loser.on_assignment(theirs, 5.1)
    winner.on_assignment(ours, 5.1)
    assert loser.round.committed is not None and loser.round.committed.digest == theirs.digest
    assert loser.round.next_target(102) is None  # 101's plan gives it nothing...
    relay = _Relay({101: (winner, won), 102: (loser, lost)})
    relay.run(5.1, 12.0)
    # ... until 101 counted it in: one plan, solved again from both standings.
    assert winner.round is not None
    plan = winner.round.committed
    assert plan is not None and plan.epoch > 0 and plan.basis is not None
    assert plan.team == (101,)  # still the plan built on 101's result (the heal's rank)
    assert loser.round.committed is not None and loser.round.committed.digest == plan.digest
    # Target 0 stays reached: nobody is sent there again; 1 and 2 are shared, 102 flies.
    queued = sorted(t for q in plan.queues.values() for t in q)
    assert queued == [1, 2] and plan.unassigned == ()
    assert plan.queues.get(102)
    assert loser.round.next_target(102) == plan.queues[102][0]
    flown = lost.autopilot[-1]
    assert isinstance(flown, Waypoint)
    target = TARGETS[plan.queues[102][0]]
    assert (flown.lat, flown.lon) == (target.lat, target.lon)
    assert any("re-based onto this plan; re-planning with it" in s for s in won.statuses())
