"""Task queues: every reachable target in exactly one queue, the same plan
whatever the input's order, the exact assignments where they are cheap."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from fleet.consensus.assignment import greedy_assign
from fleet.consensus.legs import LEG_TURN_S, great_circle_m, leg_times
from fleet.consensus.objectives import hungarian, plan_queues
from fleet.consensus.queues import QueuePlan, arrivals_of
from fleet.mission.messages import NoFlyZone, Target
from fleet.mission.objective import Objective
from tests.support.queue_optimum import optimum

Times = dict[int, list[float | None]]
_tied = st.integers(min_value=1, max_value=6).map(float)
_time = st.floats(min_value=1.0, max_value=1e3, allow_nan=False)
_answer = st.one_of(_tied, _time, st.none(), st.sampled_from([math.nan, math.inf]))


@st.composite
def instances(
    draw: st.DrawFn,
    max_uavs: int = 5,
    max_targets: int = 9,
    times: st.SearchStrategy[float | None] = _answer,
) -> tuple[Times, list[list[float]]]:
    count = draw(st.integers(min_value=0, max_value=max_targets))
    uavs = draw(st.lists(st.integers(1, 0xFFF0), unique=True, min_size=1, max_size=max_uavs))
    rows: Times = {uav: draw(st.lists(times, min_size=count, max_size=count)) for uav in uavs}
    points = draw(
        st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=count, max_size=count)
    )
    # Legs on a coarse grid: equal legs, and so ties, are common.
    legs = [
        [
            0.0 if i == j else 10.0 + abs(a[0] - b[0]) + abs(a[1] - b[1])
            for j, b in enumerate(points)
        ]
        for i, a in enumerate(points)
    ]
    return rows, legs


def _reachable(times: Times, count: int) -> set[int]:
    return {t for t in range(count) for row in times.values() if _usable(row[t])}


def _usable(time: float | None) -> bool:
    return time is not None and math.isfinite(time)


def _check_plan(plan: QueuePlan, times: Times, legs: list[list[float]]) -> None:
    count = len(legs)
    queued = [t for queue in plan.queues.values() for t in queue]
    assert len(queued) == len(set(queued)), "a target in two places"
    assert set(queued) == _reachable(times, count), "every reachable target, and only those"
    assert set(plan.unassigned) == set(range(count)) - set(queued)
    assert list(plan.queues) == sorted(times)
    for uav, queue in plan.queues.items():
        assert all(_usable(times[uav][t]) for t in queue), "only targets the UAV can reach"
        assert list(plan.arrivals[uav]) == pytest.approx(arrivals_of(times[uav], legs, queue))


@settings(max_examples=150, deadline=None)
@given(instances(), st.sampled_from(list(Objective)), st.randoms(use_true_random=False))
def test_every_reachable_target_is_in_exactly_one_queue_whatever_the_input_order(
    instance: tuple[Times, list[list[float]]], objective: Objective, rng: random.Random
) -> None:
    times, legs = instance
    plan = plan_queues(times, legs, objective)
    _check_plan(plan, times, legs)
    shuffled = list(times.items())
    rng.shuffle(shuffled)
    assert plan_queues(dict(shuffled), legs, objective) == plan


@settings(max_examples=150, deadline=None)
@given(instances(times=st.one_of(_tied, _time, st.none())))
def test_greedy_with_one_target_each_is_the_thesis_rule(
    instance: tuple[Times, list[list[float]]],
) -> None:
    times, legs = instance
    thesis = greedy_assign(times, len(legs))
    plan = plan_queues(times, legs, Objective.GREEDY)
    heads = plan.heads()
    assert {uav: heads[uav] for uav in thesis.pairs} == thesis.pairs
    if not thesis.unassigned_targets:
        assert heads == thesis.pairs and all(len(q) <= 1 for q in plan.queues.values())


@settings(max_examples=200, deadline=None)
@given(
    st.integers(1, 8).flatmap(
        lambda n: st.tuples(
            st.just(n),
            st.integers(n, 9),
            st.lists(_time, min_size=81, max_size=81),
        )
    )
)
def test_min_sum_with_one_target_each_equals_linear_sum_assignment(
    case: tuple[int, int, list[float]],
) -> None:
    count, uav_count, flat = case
    matrix = [[flat[u * count + t] for u in range(uav_count)] for t in range(count)]
    times: Times = {10 + u: [row[u] for row in matrix] for u in range(uav_count)}
    legs = [[0.0 if i == j else 50.0 for j in range(count)] for i in range(count)]
    plan = plan_queues(times, legs, Objective.MIN_SUM)
    assert all(len(q) <= 1 for q in plan.queues.values())
    rows, columns = linear_sum_assignment(matrix)
    best = math.fsum(matrix[r][c] for r, c in zip(rows, columns, strict=True))
    assert plan.total() == pytest.approx(best, rel=1e-12)


def test_hungarian_matches_scipy_on_random_rectangles() -> None:
    rng = random.Random(23)
    for _ in range(200):
        n = rng.randint(1, 12)
        m = rng.randint(n, 15)
        cost = [
            [rng.choice([rng.uniform(-50, 500), float(rng.randint(0, 3))]) for _ in range(m)]
            for _ in range(n)
        ]
        columns = hungarian(cost)
        assert len(set(columns)) == n
        rows, cols = linear_sum_assignment(cost)
        best = math.fsum(cost[r][c] for r, c in zip(rows, cols, strict=True))
        assert math.fsum(cost[r][c] for r, c in enumerate(columns)) == pytest.approx(best)


@settings(max_examples=120, deadline=None)
@given(instances(max_uavs=4, max_targets=4, times=st.one_of(_tied, _time)))
def test_min_max_with_one_target_each_is_the_bottleneck_optimum(
    instance: tuple[Times, list[list[float]]],
) -> None:
    times, legs = instance
    if len(legs) > len(times):
        return
    plan = plan_queues(times, legs, Objective.MIN_MAX)
    assert all(len(q) <= 1 for q in plan.queues.values())
    # Brute force over every one-each assignment.
    import itertools

    uavs = sorted(times)
    best = min(
        max((times[u][t] or 0.0 for t, u in enumerate(chosen)), default=0.0)
        for chosen in itertools.permutations(uavs, len(legs))
    )
    assert plan.makespan() == best


@settings(max_examples=60, deadline=None)
@given(instances(max_uavs=3, max_targets=7, times=st.one_of(_tied, _time, st.none())))
def test_no_plan_beats_the_exact_optimum(
    instance: tuple[Times, list[list[float]]],
) -> None:
    times, legs = instance
    for objective, measure in (
        (Objective.MIN_SUM, QueuePlan.total),
        (Objective.MIN_MAX, QueuePlan.makespan),
    ):
        best = optimum(times, legs, objective)
        value = measure(plan_queues(times, legs, objective))
        assert value >= best - 1e-6 * max(1.0, best)


def test_more_targets_than_uavs_every_uav_gets_a_tour() -> None:
    # Two UAVs at the two ends of a line of six targets 1 km apart.
    targets = [Target(35.72, -120.765 + 0.011 * i, 600.0) for i in range(6)]
    legs = leg_times(targets)
    times: Times = {
        74: [30.0 + 45.0 * i for i in range(6)],
        112: [30.0 + 45.0 * (5 - i) for i in range(6)],
    }
    for objective in Objective:
        plan = plan_queues(times, legs, objective)
        assert sorted(plan.queues[74] + plan.queues[112]) == list(range(6))
        assert plan.queues[74][0] == 0 and plan.queues[112][0] == 5
        assert set(plan.queues[74]) == {0, 1, 2} and set(plan.queues[112]) == {3, 4, 5}


def test_a_target_only_a_busy_uav_reaches_is_queued_behind_its_first() -> None:
    # Thesis: target 1 unassigned, for 74 took target 0 and 112 has no time to it.
    times: Times = {74: [10.0, 20.0], 112: [15.0, None]}
    legs = [[0.0, 30.0], [30.0, 0.0]]
    for objective in Objective:
        plan = plan_queues(times, legs, objective)
        assert plan.unassigned == ()
        assert 1 in plan.queues[74]


def test_a_target_nobody_reaches_is_unassigned() -> None:
    times: Times = {74: [10.0, None], 112: [15.0, math.nan]}
    plan = plan_queues(times, [[0.0, 1.0], [1.0, 0.0]], Objective.MIN_SUM)
    assert plan.unassigned == (1,)


def test_rows_of_the_wrong_length_are_named() -> None:
    with pytest.raises(ValueError, match="UAV 74"):
        plan_queues({74: [1.0]}, [[0.0, 1.0], [1.0, 0.0]])


def test_legs_are_great_circle_time_plus_the_turn() -> None:
    a, b = Target(35.72, -120.765, 600.0), Target(35.73, -120.765, 600.0)
    assert great_circle_m(a, b) == pytest.approx(1112.0, rel=1e-3)
    legs = leg_times([a, b], speed_mps=20.0)
    assert legs[0][1] == legs[1][0] == pytest.approx(1112.0 / 20.0 + LEG_TURN_S, rel=1e-3)
    assert legs[0][0] == 0.0


def test_a_leg_through_a_no_fly_zone_is_the_route_around_it() -> None:
    """The legs of a mission with zones: a leg whose line crosses a zone is the route
    around it (longer than the great circle); a clear leg is unchanged."""
    a = Target(35.70, -120.80, 600.0)
    b = Target(35.70, -120.70, 600.0)
    c = Target(35.75, -120.80, 600.0)
    # A box across the line a-b, clear of a-c.
    wall = NoFlyZone(ring=((35.69, -120.76), (35.71, -120.76), (35.71, -120.74), (35.69, -120.74)))
    plain = leg_times([a, b, c])
    zoned = leg_times([a, b, c], zones=(wall,))
    assert plain[0][1] < zoned[0][1] < math.inf
    assert zoned[0][2] == plain[0][2]


def test_an_infinite_leg_is_never_queued() -> None:
    """A target no route reaches from another (an infinite leg) is not queued after it."""
    legs = [[0.0, math.inf], [math.inf, 0.0]]
    plan = plan_queues({1: (10.0, 20.0)}, legs, Objective.GREEDY)
    assert plan.queues[1] == (0,)
