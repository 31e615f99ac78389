"""The min-sum proposal's search (fleet.solver.min_sum_search): it never makes a plan
worse, keeps every target in exactly one queue, gives the same plan for the same seed,
and finds the optimum of a small instance (found here by enumerating every plan)."""

from __future__ import annotations

import itertools
import math
import random

import pytest

from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import Queues, finish
from fleet.mission.objective import Objective
from fleet.solver.min_sum_search import search_min_sum


def _instance(
    seed: int, uavs: int, targets: int
) -> tuple[dict[int, list[float | None]], list[list[float]]]:
    rng = random.Random(seed)
    goals = [(rng.uniform(0, 6000), rng.uniform(0, 6000)) for _ in range(targets)]
    starts = [(rng.uniform(0, 6000), rng.uniform(0, 6000)) for _ in range(uavs)]
    times: dict[int, list[float | None]] = {
        10 + u: [math.dist(s, g) / 22.0 + 15.0 for g in goals] for u, s in enumerate(starts)
    }
    legs = [[0.0 if a == b else math.dist(a, b) / 22.0 + 15.0 for b in goals] for a in goals]
    return times, legs


def _total(queues: Queues, times: dict[int, list[float | None]], legs: list[list[float]]) -> float:
    return finish(queues, times, legs).total()


def _optimum(times: dict[int, list[float | None]], legs: list[list[float]]) -> float:
    """Every split of the targets between the two UAVs, every order of each queue."""
    uavs = sorted(times)
    count = len(legs)
    best = math.inf
    for owners in itertools.product(range(2), repeat=count):
        mine = [[t for t in range(count) if owners[t] == k] for k in range(2)]
        sums = [
            min(_total({uavs[k]: list(order)}, {uavs[k]: times[uavs[k]]}, legs)
                for order in itertools.permutations(mine[k]))
            for k in range(2)
        ]  # fmt: skip
        best = min(best, sum(sums))
    return best


@pytest.mark.parametrize("seed", range(4))
def test_the_search_finds_the_optimum_of_a_small_instance(seed: int) -> None:
    times, legs = _instance(seed, 2, 7)
    start = {uav: list(q) for uav, q in plan_queues(times, legs, Objective.MIN_SUM).queues.items()}
    found = search_min_sum(start, times, legs)
    assert _total(found, times, legs) == pytest.approx(_optimum(times, legs), rel=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_never_worse_every_target_once_and_the_same_for_a_seed(seed: int) -> None:
    times, legs = _instance(100 + seed, 5, 30)
    start = {uav: list(q) for uav, q in plan_queues(times, legs, Objective.MIN_SUM).queues.items()}
    found = search_min_sum(start, times, legs, rounds=10, seed=3)
    assert _total(found, times, legs) <= _total(start, times, legs)
    assert sorted(t for q in found.values() for t in q) == list(range(30))
    assert search_min_sum(start, times, legs, rounds=10, seed=3) == found


def test_a_proposal_for_min_sum_is_no_worse_than_the_baseline() -> None:
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    from fleet.solver.pyvrp_plan import solve_queues

    times, legs = _instance(7, 3, 12)
    baseline = plan_queues(times, legs, Objective.MIN_SUM)
    proposed = solve_queues(times, legs, Objective.MIN_SUM)
    assert _total(proposed, times, legs) <= baseline.total() + 1e-9
