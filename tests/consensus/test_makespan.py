"""The min-max search beyond relocations: a bisection on the last arrival by ruin and
recreate, moves on the longest queue, a tightening bound on the last arrival. Never
worse, every target kept once, the same plan every time."""

from __future__ import annotations

import math
import random
from collections.abc import Iterable

import pytest

from fleet.consensus import tighten as tighten_module
from fleet.consensus.improve import improve
from fleet.consensus.makespan import ruin_and_recreate, shorten_longest
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import finish, greedy_queues
from fleet.consensus.tighten import _Search, tighten
from fleet.mission.objective import Objective


def _instance(
    seed: int, uavs: int, targets: int
) -> tuple[dict[int, list[float | None]], list[list[float]]]:
    rng = random.Random(seed)
    side = 2000.0 * math.sqrt(targets)
    where = [(rng.uniform(0, side), rng.uniform(0, side)) for _ in range(uavs)]
    goals = [(rng.uniform(0, side), rng.uniform(0, side)) for _ in range(targets)]
    times: dict[int, list[float | None]] = {
        101 + i: [math.dist(u, g) / 22.0 for g in goals] for i, u in enumerate(where)
    }
    legs = [[math.dist(a, b) / 22.0 for b in goals] for a in goals]
    return times, legs


def test_the_searches_never_lengthen_the_plan_and_keep_every_target_once() -> None:
    for seed in range(6):
        times, legs = _instance(seed, 4, 18)
        start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
        before = finish(start, times, legs).makespan()
        for search in (ruin_and_recreate, shorten_longest, tighten):
            after = search(start, times, legs)
            assert sorted(t for q in after.values() for t in q) == list(range(18))
            assert finish(after, times, legs).makespan() <= before + 1e-9


def test_the_min_max_plan_is_the_same_every_time_and_no_longer_than_the_relocations() -> None:
    times, legs = _instance(7, 5, 20)
    first = plan_queues(times, legs, Objective.MIN_MAX)
    assert plan_queues(times, legs, Objective.MIN_MAX) == first
    relocated = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
    assert first.makespan() <= finish(relocated, times, legs).makespan() + 1e-9


def test_an_unreachable_head_is_never_made() -> None:
    """UAV 102 reaches target 0 only: the searches never give it another first."""
    times, legs = _instance(3, 2, 6)
    times[102] = [times[102][0], *([None] * 5)]
    plan = plan_queues(times, legs, Objective.MIN_MAX)
    assert set(plan.queues[102]) <= {0}
    assert sorted(t for q in plan.queues.values() for t in q) == list(range(6))


def test_the_tightening_bound_shortens_a_plan_the_longest_queue_moves_leave() -> None:
    """A plan the relocations and the longest-queue moves cannot shorten any more: the
    bound on the last arrival still does, on most of these seeds, and is the same plan
    twice."""
    shorter = 0
    for seed in range(3):
        times, legs = _instance(seed, 6, 30)
        start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
        start = shorten_longest(start, times, legs)
        after = tighten(start, times, legs)
        assert tighten(start, times, legs) == after
        before, span = (finish(q, times, legs).makespan() for q in (start, after))
        assert span <= before + 1e-9
        shorter += span < 0.99 * before
    assert shorter >= 2


def test_the_tightening_bound_never_gives_a_uav_a_target_it_cannot_reach() -> None:
    times, legs = _instance(4, 3, 12)
    for t in range(6):
        times[103][t] = None  # 103 reaches the last six only
    times[102][11] = math.inf
    start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
    after = tighten(start, times, legs)
    assert set(after[103]) <= set(range(6, 12))
    assert 11 not in after[102]
    assert sorted(t for q in after.values() for t in q) == list(range(12))


def test_the_tightening_bound_from_several_starts_is_the_same_plan_in_any_input_order() -> None:
    """Up to 2,000 pairs the bound is tightened from the plan given and from each regret
    insertion's plan, each with its own seed: the same plan twice, and whatever the order
    in which the UAVs' rows and queues were put in the mappings."""
    times, legs = _instance(11, 5, 20)
    start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
    first = tighten(start, times, legs)
    assert tighten(start, times, legs) == first
    reversed_times = {uav: times[uav] for uav in sorted(times, reverse=True)}
    reversed_start = {uav: start[uav] for uav in sorted(start, reverse=True)}
    assert tighten(reversed_start, reversed_times, legs) == first
    assert sorted(t for q in first.values() for t in q) == list(range(20))
    assert finish(first, times, legs).makespan() <= finish(start, times, legs).makespan() + 1e-9


def test_several_starts_shorten_a_plan_one_start_leaves() -> None:
    """The plan given is often a poor basin: from it and the regret insertion's plans (a
    share of the moves each), the search ends lower than from it alone with all the moves
    on most of these seeds, and never higher."""
    shorter = 0
    for seed in (3, 7, 9):
        times, legs = _instance(seed, 5, 20)
        start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
        several = finish(tighten(start, times, legs), times, legs).makespan()
        search = _Search(start, times, legs)
        alone = search.bisect(search.snapshot())
        one = finish({uav: alone[k][1:] for k, uav in enumerate(search.uavs)}, times, legs)
        assert several <= one.makespan() + 1e-9
        shorter += several < 0.99 * one.makespan()
    assert shorter >= 2


def test_the_regret_insertion_of_three_queues_places_every_target_once_the_same_way() -> None:
    """The regret insertion's starts weigh the second- and third-best queues too (regret
    3): every target placed once, only in a queue whose UAV reaches it, the same plan
    twice."""
    times, legs = _instance(5, 4, 16)
    times[104][3] = None
    start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
    plans = []
    for _ in range(2):
        search = _Search(start, times, legs)
        assert search.build(search.span() * 0.9, 3)
        plans.append(search.snapshot())
    assert plans[0] == plans[1]
    assert sorted(t for route in plans[0] for t in route[1:]) == list(range(16))
    assert 3 not in plans[0][search.uavs.index(104)]


class _FirstChoices(random.Random):
    """The rounds' choices made plain: the first queue over the bound, its first target,
    and that target alone removed."""

    def randrange(self, *args: int, **_: object) -> int:  # type: ignore[override]
        return 0

    def randint(self, a: int, b: int) -> int:
        return a


class _RecreateOnly(_Search):
    """A round's ruin and recreate without the descent after it."""

    def descend(self, targets: Iterable[int]) -> None:
        pass


def test_a_round_puts_its_seed_back_in_another_queue() -> None:
    """The target a round takes from a queue over the bound is put back in another
    queue, where it adds the least there, and the plan changes: put back where it added
    the least over every queue, it went back where it was (from a plan the descent left,
    most often its cheapest place) and the round rebuilt the plan it started from."""
    checked = 0
    for seed in range(6):
        times, legs = _instance(seed, 4, 12)
        start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
        search = _RecreateOnly(start, times, legs)
        search.bound = 0.9 * search.span()
        _Search.descend(search, search.targets)
        over = [k for k, a in enumerate(search.arrivals) if len(a) > 1 and a[-1] > search.bound]
        if not over:
            continue
        before = search.snapshot()
        home, target = over[0], search.routes[over[0]][1]
        search.rng = _FirstChoices()
        assert search.kick()
        assert search.where[target][0] != home
        assert search.snapshot() != before
        assert sorted(t for route in search.routes for t in route[1:]) == list(range(12))
        checked += 1
    assert checked >= 4


def test_the_lowest_ends_searched_again_never_end_higher_and_serve_every_target_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The several starts' lowest ends are each searched again with their own seed: the
    plan is never longer than without that, the same plan twice, every target once."""
    for seed in (2, 6):
        times, legs = _instance(seed, 5, 20)
        start = improve(greedy_queues(times, legs), times, legs, Objective.MIN_MAX)
        again = tighten(start, times, legs)
        assert tighten(start, times, legs) == again
        assert sorted(t for q in again.values() for t in q) == list(range(20))
        with monkeypatch.context() as patch:
            patch.setattr(tighten_module, "CONTINUED", 0)
            once = tighten(start, times, legs)
        assert finish(again, times, legs).makespan() <= finish(once, times, legs).makespan() + 1e-9
