"""A round's plan on the wire: queues in the report, a digest per objective,
and a teammate's report with impossible queues refused whole."""

from __future__ import annotations

import msgspec
import pytest

from fleet.consensus.assignment import results_digest
from fleet.consensus.mission_round import MissionRound, assignment_problem
from fleet.consensus.objectives import plan_digest
from fleet.mission.messages import AssignmentReport, MissionTargets, Target, UavResult
from fleet.mission.objective import Objective

TARGETS = tuple(Target(35.7 + 0.01 * i, -120.8, 600.0) for i in range(4))
TIMES = {74: (10.0, 50.0, 60.0, 70.0), 112: (40.0, 20.0, 30.0, 90.0)}


def decided(objective: Objective) -> AssignmentReport:
    mission = MissionTargets(7, (74, 112), TARGETS, objective=objective)
    mission_round = MissionRound(mission, 74, 0.0)
    for uav, times in TIMES.items():
        mission_round.add_result(UavResult(7, uav, times))
    return mission_round.decide({74, 112})


def test_the_report_carries_every_queue_and_arrival_and_the_objective() -> None:
    report = decided(Objective.GREEDY)
    queued = sorted(t for q in report.queues.values() for t in q)
    assert queued == [0, 1, 2, 3] and report.unassigned == () and report.unserved == {}
    assert report.pairs == {uav: q[0] for uav, q in report.queues.items()}
    assert all(len(report.arrivals[u]) == len(q) for u, q in report.queues.items())
    assert report.eta_s == report.arrivals[74][0] and report.objective == Objective.GREEDY


def test_the_digest_covers_the_objective_and_greedy_keeps_the_results_digest() -> None:
    digests = {objective: decided(objective).digest for objective in Objective}
    assert digests[Objective.GREEDY] == results_digest(TIMES)
    assert len(set(digests.values())) == 3
    assert plan_digest("abc", Objective.MIN_SUM) == plan_digest("abc", Objective.MIN_SUM)


@pytest.mark.parametrize(
    ("queues", "why"),
    [
        ({74: (0, 2), 112: (1, 2)}, "queued twice"),
        ({74: (0, 9), 112: (1,)}, "beyond"),
        ({74: (0,), 999: (1,)}, "outside"),
        ({74: (3, 0), 112: (1,)}, "does not start"),
    ],
)
def test_impossible_queues_are_refused_whole(queues: dict[int, tuple[int, ...]], why: str) -> None:
    good = decided(Objective.GREEDY)
    bad = msgspec.structs.replace(good, uav=112, queues=queues)
    mission = MissionTargets(7, (74, 112), TARGETS)
    problem = assignment_problem(bad, mission)
    assert problem is not None and why in problem
    assert assignment_problem(good, mission) is None


def test_an_old_mission_json_is_greedy() -> None:
    raw = b'{"mission":3,"team":[74],"targets":[{"lat":1.0,"lon":2.0,"alt":3.0}]}'
    assert msgspec.json.decode(raw, type=MissionTargets).objective == Objective.GREEDY
