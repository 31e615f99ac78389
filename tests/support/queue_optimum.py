"""The exact optimum of a small queue problem, by dynamic programming over subsets.

For the tests and `bench/bench_queues.py`: every UAV serves a subset of the targets in
the best order for it, and the subsets partition the reachable targets. A path's sum of
arrivals counts each leg once per target still to come, so the best order of a subset S
from target j is `f(S, j) = min over t in S of |S| * leg(j, t) + f(S - t, t)`, shared by
every UAV; a UAV's best cost for S starts with |S| times its approach time. The last
arrival is the same recursion without the factor. The partition is a second DP over the
UAVs (3^T steps): T = 10 is about a second.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from functools import cache

from fleet.mission.objective import Objective


def optimum(
    times: Mapping[int, Sequence[float | None]],
    legs: Sequence[Sequence[float]],
    objective: Objective,
) -> float:
    """The least total (MIN_SUM) or last arrival (MIN_MAX) over every plan that queues
    every target some UAV can reach (a UAV queues only targets it has a time to)."""
    count = len(legs)
    min_sum = objective is Objective.MIN_SUM
    inf = math.inf

    @cache
    def tail(subset: int, start: int) -> float:
        if not subset:
            return 0.0
        size = subset.bit_count()
        best = inf
        for t in range(count):
            if subset >> t & 1:
                leg = legs[start][t] * (size if min_sum else 1)
                best = min(best, leg + tail(subset & ~(1 << t), t))
        return best

    def uav_cost(row: Sequence[float | None], subset: int) -> float:
        size = subset.bit_count()
        best = inf
        for t in range(count):
            if subset >> t & 1:
                if any(subset >> s & 1 and not _usable(row[s]) for s in range(count)):
                    return inf
                first = row[t]
                assert first is not None
                best = min(best, first * (size if min_sum else 1) + tail(subset & ~(1 << t), t))
        return best

    reachable = 0
    for t in range(count):
        if any(_usable(row[t]) for row in times.values()):
            reachable |= 1 << t
    # best[S]: the cost of serving exactly S with the UAVs so far.
    best = {0: 0.0}
    for uav in sorted(times):
        row = times[uav]
        costs: dict[int, float] = {}
        after: dict[int, float] = dict(best)
        for served, value in best.items():
            rest = reachable & ~served
            sub = rest
            while sub:
                if sub not in costs:
                    costs[sub] = uav_cost(row, sub)
                own = costs[sub]
                if own < inf:
                    total = value + own if min_sum else max(value, own)
                    key = served | sub
                    if total < after.get(key, inf):
                        after[key] = total
                sub = (sub - 1) & rest
        best = after
    return best.get(reachable, inf)


def _usable(time: float | None) -> bool:
    return time is not None and math.isfinite(time)
