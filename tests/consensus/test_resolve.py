"""Solving what is left: an epoch's plan from the taking-part UAVs' fresh standings, each
keeping its current target unless the objective gains; the append rule when a standing
is missing."""

from __future__ import annotations

import itertools
import random
from collections.abc import Sequence

import pytest

from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import LegTables, Matrix, Rows, arrivals_of
from fleet.consensus.replan import replan
from fleet.consensus.resolve import (
    NO_TAKER,
    Standing,
    remaining_targets,
    resolve,
    resolve_digest,
    solve_epoch,
)
from fleet.mission.messages import AssignmentReport
from fleet.mission.objective import Objective
from tests.support.greedy_report import greedy_report

SPEED = 10.0


def line_times(where: float, targets: tuple[float, ...]) -> tuple[float | None, ...]:
    """Approach times along a line at 10 m/s."""
    return tuple(abs(t - where) / SPEED for t in targets)


def line_legs(targets: tuple[float, ...]) -> list[list[float]]:
    return [[abs(a - b) / SPEED for b in targets] for a in targets]


def base_report(times: dict[int, tuple[float | None, ...]]) -> AssignmentReport:
    return greedy_report(times)


# Targets at 0 m, 1000 m and 2000 m. At the start 74 is at 0, 112 at 1000, 200 at 1900:
# each takes the target next to it. 112 is then lost while 74, done with target 0, has
# flown on to 1100 m: it is now the closest to target 1 (10 s), 200 still 90 s away.
TARGETS = (0.0, 1000.0, 2000.0)
LEGS = line_legs(TARGETS)
START = {
    74: line_times(0.0, TARGETS),
    112: line_times(1000.0, TARGETS),
    200: line_times(1900.0, TARGETS),
}


def test_a_survivor_that_moved_closer_gets_the_orphan_from_its_fresh_times() -> None:
    base = base_report(START)
    assert base.pairs == {74: 0, 112: 1, 200: 2}
    fallback = replan(base, START, {112}, LEGS)
    # The append rule, from the start's times: 74 would reach target 1 at 0 + 100 s
    # after target 0, 200 at 10 + 100 s: 74 takes it.
    assert fallback.plan.queues == {74: (0, 1), 200: (2,)}
    standings = {
        74: Standing(line_times(1100.0, TARGETS), None, frozenset({0})),
        200: Standing(line_times(1950.0, TARGETS), 2),
    }
    for objective in Objective:
        plan, fresh = solve_epoch(fallback, standings, LEGS, objective)
        assert fresh
        assert plan.plan.queues == {74: (1,), 200: (2,)}, objective
        assert plan.plan.arrivals[74] == pytest.approx((10.0,))
        assert plan.epoch == fallback.epoch and plan.released == fallback.released
        assert plan.digest != fallback.digest and plan.unserved == {}


def test_a_missing_standing_falls_back_to_the_append_rule() -> None:
    fallback = replan(base_report(START), START, {112}, LEGS)
    standings = {74: Standing(line_times(1100.0, TARGETS), None, frozenset({0}))}
    plan, fresh = solve_epoch(fallback, standings, LEGS, Objective.MIN_SUM)
    assert not fresh and plan is fallback


def test_standings_of_released_uavs_are_ignored() -> None:
    fallback = replan(base_report(START), START, {112}, LEGS)
    standings = {
        74: Standing(line_times(0.0, TARGETS)),
        112: Standing(line_times(1000.0, TARGETS), 1),  # released: takes no part
        200: Standing(line_times(1900.0, TARGETS), 2),
    }
    plan, fresh = solve_epoch(fallback, standings, LEGS, Objective.MIN_SUM)
    assert fresh and set(plan.plan.queues) == {74, 200}
    assert 1 in plan.plan.queues[74] + plan.plan.queues[200]


# Targets at 1000 m and 50 m: 74 at 0 m flies to target 0 (1000 m), 112 idle at 950 m.
SWAP_TARGETS = (1000.0, 50.0)
SWAP_LEGS = line_legs(SWAP_TARGETS)
SWAP = {
    74: Standing(line_times(0.0, SWAP_TARGETS), 0),
    112: Standing(line_times(950.0, SWAP_TARGETS)),
}


def test_a_uav_changes_its_target_when_the_objective_gains() -> None:
    # The greedy, with no measure of its own, gains by the total of arrivals.
    for objective in Objective:
        solved = resolve(SWAP, (0, 1), SWAP_LEGS, objective)
        assert not solved.kept
        assert solved.plan.queues == {74: (1,), 112: (0,)}, objective


def test_a_swap_that_gains_too_little_is_not_made() -> None:
    # 74 at 0 m flies to target 0 (1000 m), 112 idle next to both targets: one target
    # each, 74's arrival (100 s) is the last either way, so min-max gains nothing by a
    # swap and 74 keeps its target.
    targets = (1000.0, 1000.0002)
    standings = {
        74: Standing(line_times(0.0, targets), 0),
        112: Standing(line_times(1000.0001, targets)),
    }
    solved = resolve(standings, (0, 1), line_legs(targets), Objective.MIN_MAX)
    assert solved.kept and solved.plan.queues[74] == (0,)


def test_a_uav_keeps_its_target_when_changing_gains_nothing() -> None:
    # 74 at 900 m flying to target 0 (1000 m), 112 at 100 m: already the best plan.
    standings = {
        74: Standing(line_times(900.0, SWAP_TARGETS), 0),
        112: Standing(line_times(100.0, SWAP_TARGETS)),
    }
    for objective in Objective:
        solved = resolve(standings, (0, 1), SWAP_LEGS, objective)
        assert solved.kept and solved.plan.queues == {74: (0,), 112: (1,)}


def test_a_kept_target_comes_first_and_the_rest_is_solved_after_it() -> None:
    targets = (100.0, 200.0, 300.0, -500.0)
    legs = line_legs(targets)
    standings = {
        74: Standing(line_times(0.0, targets), 0),  # flying to 100 m
        112: Standing(line_times(-400.0, targets)),
    }
    solved = resolve(standings, range(4), legs, Objective.GREEDY)
    assert solved.kept and solved.plan.queues[74][:3] == (0, 1, 2)
    assert set(solved.plan.queues[74]) | set(solved.plan.queues[112]) == {0, 1, 2, 3}
    assert solved.plan.arrivals[74] == pytest.approx(
        tuple(arrivals_of(standings[74].times, legs, solved.plan.queues[74]))
    )


def test_a_target_two_uavs_fly_is_kept_by_the_one_closer_to_it() -> None:
    targets = (500.0, -1000.0)
    standings = {
        74: Standing(line_times(0.0, targets), 0),
        112: Standing(line_times(400.0, targets), 0),
    }
    solved = resolve(standings, (0, 1), line_legs(targets), Objective.GREEDY)
    assert solved.plan.queues[112][0] == 0
    assert solved.plan.queues[74] == (1,)


def test_reached_and_removed_targets_are_not_planned_again() -> None:
    standings = {
        74: Standing(line_times(0.0, TARGETS), None, frozenset({0})),
        200: Standing(line_times(1900.0, TARGETS), None, frozenset()),
    }
    assert remaining_targets(3, (), standings) == (1, 2)
    assert remaining_targets(3, (2,), standings) == (1,)
    solved = resolve(standings, (1,), LEGS, Objective.MIN_SUM)
    assert {t for q in solved.plan.queues.values() for t in q} == {1}


def test_a_target_nobody_taking_part_can_reach_is_unserved_with_the_reason() -> None:
    standings = {74: Standing((1.0, None, 3.0)), 200: Standing((2.0, None, None))}
    solved = resolve(standings, (0, 1, 2), LEGS, Objective.MIN_SUM)
    assert solved.plan.unassigned == (1,)
    assert solved.unserved == {1: NO_TAKER}


def test_the_plan_and_digest_do_not_depend_on_the_order_given() -> None:
    rng = random.Random(7)
    targets = tuple(rng.uniform(0, 3000) for _ in range(7))
    legs = line_legs(targets)
    standings = {
        uav: Standing(line_times(rng.uniform(0, 3000), targets), rng.choice((None, 0, 3)))
        for uav in (74, 112, 200)
    }
    plans = set()
    digests = set()
    for order in itertools.permutations(standings):
        shuffled = {uav: standings[uav] for uav in order}
        solved = resolve(shuffled, reversed(range(7)), legs, Objective.MIN_MAX)
        plans.add(tuple(sorted(solved.plan.queues.items())))
        digests.add(resolve_digest("basis", shuffled, range(7), Objective.MIN_MAX))
    assert len(plans) == 1 and len(digests) == 1


def test_the_digest_changes_with_any_part_of_the_input() -> None:
    standings = {74: Standing((1.0, 2.0, 3.0), 0), 200: Standing((2.0, 1.0, 4.0))}
    digest = resolve_digest("basis", standings, (0, 1, 2), Objective.MIN_SUM)
    changed = [
        resolve_digest("other", standings, (0, 1, 2), Objective.MIN_SUM),
        resolve_digest("basis", standings, (0, 1, 2), Objective.MIN_MAX),
        resolve_digest("basis", standings, (0, 1), Objective.MIN_SUM),
        resolve_digest(
            "basis", {**standings, 74: Standing((1.0, 2.0, 3.5), 0)}, (0, 1, 2), Objective.MIN_SUM
        ),
        resolve_digest(
            "basis", {**standings, 74: Standing((1.0, 2.0, 3.0), 1)}, (0, 1, 2), Objective.MIN_SUM
        ),
        resolve_digest(
            "basis",
            {**standings, 74: Standing((1.0, 2.0, 3.0), 0, frozenset({2}))},
            (0, 1, 2),
            Objective.MIN_SUM,
        ),
    ]
    assert len({digest, *changed}) == len(changed) + 1


class _Tables(LegTables):
    """The same matrix as a LegTables: a subset must time a queue the same either way."""

    def __init__(self, matrix: list[list[float]]) -> None:
        self.matrix = matrix

    @property
    def count(self) -> int:
        return len(self.matrix)

    def of(self, uav: int) -> Rows:
        return self.matrix

    def reference(self) -> Matrix:
        return self.matrix

    def arrivals(self, uav: int, first: float, queue: Sequence[int]) -> list[float]:
        out = [first]
        for i, j in itertools.pairwise(queue):
            out.append(out[-1] + self.matrix[i][j])
        return out


@pytest.mark.parametrize("objective", list(Objective))
def test_each_uavs_own_legs_plan_as_the_shared_table(objective: Objective) -> None:
    rng = random.Random(11)
    targets = tuple(rng.uniform(0, 5000) for _ in range(9))
    legs = line_legs(targets)
    standings = {
        uav: Standing(line_times(rng.uniform(0, 5000), targets), flying)
        for uav, flying in ((74, 2), (112, None), (200, 5))
    }
    left = (0, 2, 3, 5, 6, 8)
    shared = resolve(standings, left, legs, objective)
    own = resolve(standings, left, _Tables(legs), objective)
    assert shared == own


@pytest.mark.parametrize("objective", [Objective.MIN_SUM, Objective.MIN_MAX])
def test_resolving_never_does_worse_than_solving_from_scratch_by_more_than_keeping(
    objective: Objective,
) -> None:
    # Without any current target the resolved plan is the plan from scratch.
    rng = random.Random(5)
    targets = tuple(rng.uniform(0, 5000) for _ in range(8))
    legs = line_legs(targets)
    standings = {uav: Standing(line_times(rng.uniform(0, 5000), targets)) for uav in (74, 112)}
    rows = {uav: s.times for uav, s in standings.items()}
    scratch = plan_queues(rows, legs, objective)
    solved = resolve(standings, range(8), legs, objective)
    assert solved.plan.queues == scratch.queues


def test_times_of_the_wrong_length_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="UAV 74: expected 3 approach times, got 2"):
        resolve({74: Standing((1.0, 2.0))}, (0, 1), LEGS, Objective.MIN_SUM)
