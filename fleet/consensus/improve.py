"""Local search on queues for `min-sum` and `min-max`: relocate one target at a time.

The queue problem with more targets than UAVs is a multi-vehicle routing problem
(min-sum: the minimum-latency problem, NP-hard), so it is solved by a documented
heuristic: start from the greedy queues, then move one target to another place (in its
own queue or another UAV's) whenever that strictly improves the objective's key,

    min-sum: (total of arrival times, last arrival)
    min-max: (last arrival, total of arrival times)

first improvement, targets in increasing index, places in increasing (Piccolo ID,
position). The places tried for a target are its granular neighbourhood: before or after
one of its `NEIGHBOURS` nearest targets (by leg time), or at the head of the queue of
one of the `NEIGHBOURS` UAVs with its best approach times. At most `MAX_PASSES` passes
over every target: the plan never depends on the machine's speed. The measured gap to
the optimum is in docs/benchmarks.md. Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from fleet.consensus.queues import Legs, Queues, Times, usable
from fleet.mission.objective import Objective

#: Passes over every target at most (a pass with no improvement ends the search).
MAX_PASSES = 8
#: How many nearest targets, and best-placed UAVs, a target's new places are next to.
NEIGHBOURS = 8


def improve(queues: Queues, times: Times, legs: Legs, objective: Objective) -> Queues:
    """`queues` improved for `objective` (a new mapping; the input is left as it was)."""
    search = _Search({uav: list(q) for uav, q in queues.items()}, times, legs, objective)
    for _ in range(MAX_PASSES):
        if not search.one_pass():
            break
    return search.queues


def queue_sum_end(
    row: Sequence[float | None], legs: Legs, queue: Sequence[int]
) -> tuple[float, float]:
    """(sum of arrivals, last arrival) of one queue; (0, 0) when empty."""
    if not queue:
        return 0.0, 0.0
    first = row[queue[0]]
    assert first is not None
    clock = total = first
    previous = queue[0]
    for target in queue[1:]:
        clock += legs[previous][target]
        total += clock
        previous = target
    return total, clock


class _Search:
    def __init__(self, queues: Queues, times: Times, legs: Legs, objective: Objective) -> None:
        self.queues = queues
        self.times = times
        self.legs = legs
        self.min_max = objective is Objective.MIN_MAX
        self.uavs = sorted(queues)
        count = len(legs)
        self.near = [
            sorted((j for j in range(count) if j != i), key=_by_leg(legs, i))[:NEIGHBOURS]
            for i in range(count)
        ]
        self.best_uavs = [
            sorted(
                (uav for uav in self.uavs if usable(times[uav][t])),
                key=_by_time(times, t),
            )[:NEIGHBOURS]
            for t in range(count)
        ]
        self.position: dict[int, tuple[int, int]] = {}
        self.cost = {uav: queue_sum_end(times[uav], legs, q) for uav, q in queues.items()}
        self._refresh()

    def _refresh(self) -> None:
        self.total = math.fsum(c[0] for c in self.cost.values())
        ends = sorted(((c[1], uav) for uav, c in self.cost.items()), reverse=True)
        self.top = ends[:3]

    def _key(self, total: float, makespan: float) -> tuple[float, float]:
        return (makespan, total) if self.min_max else (total, makespan)

    def _others_end(self, a: int, b: int) -> float:
        for end, uav in self.top:
            if uav not in (a, b):
                return end
        return 0.0

    def one_pass(self) -> bool:
        """Try every target's places once; True if some move was made."""
        moved = False
        self.position = self._positions()
        for target in sorted(self.position):
            if self._relocate(target, self.position[target][0]):
                moved = True
                self.position = self._positions()
        return moved

    def _positions(self) -> dict[int, tuple[int, int]]:
        """Each queued target's (UAV, index in its queue)."""
        return {t: (uav, i) for uav, q in self.queues.items() for i, t in enumerate(q)}

    def _places(self, target: int, home: int) -> list[tuple[int, int]]:
        """(UAV, position in its queue without `target`) to try, sorted, no repeats."""
        position = self.position
        places: set[tuple[int, int]] = set()
        for near in self.near[target]:
            if near not in position:
                continue
            uav, index = position[near]
            if uav == home and index > position[target][1]:
                index -= 1  # positions counted once `target` is out of its queue
            places.add((uav, index))
            places.add((uav, index + 1))
        for uav in self.best_uavs[target]:
            places.add((uav, 0))
        return sorted(p for p in places if usable(self.times[p[0]][target]))

    def _relocate(self, target: int, home: int) -> bool:
        times, legs = self.times, self.legs
        home_queue = self.queues[home]
        start = self.position[target][1]
        without = home_queue[:start] + home_queue[start + 1 :]
        if without and not usable(times[home][without[0]]):
            return False  # the next target cannot head this UAV's queue
        home_cost = queue_sum_end(times[home], legs, without)
        current = self._key(self.total, self.top[0][0] if self.top else 0.0)
        for uav, index in self._places(target, home):
            base = without if uav == home else self.queues[uav]
            if uav == home and index == start:
                continue  # where it is now
            if index > len(base):
                continue
            trial = [*base[:index], target, *base[index:]]
            if not usable(times[uav][trial[0]]):
                continue
            new_cost = queue_sum_end(times[uav], legs, trial)
            if uav == home:
                total = self.total - self.cost[home][0] + new_cost[0]
                makespan = max(self._others_end(home, home), new_cost[1])
            else:
                total = self.total - self.cost[home][0] - self.cost[uav][0]
                total += home_cost[0] + new_cost[0]
                makespan = max(self._others_end(home, uav), home_cost[1], new_cost[1])
            if self._key(total, makespan) < current:
                if uav != home:
                    self.queues[home] = without
                    self.cost[home] = home_cost
                self.queues[uav] = trial
                self.cost[uav] = new_cost
                self._refresh()
                return True
        return False


def _by_leg(legs: Legs, i: int) -> Callable[[int], tuple[float, int]]:
    return lambda j: (legs[i][j], j)


def _by_time(times: Times, t: int) -> Callable[[int], tuple[float, int]]:
    return lambda uav: (_finite(times[uav][t]), uav)


def _finite(time: float | None) -> float:
    return time if time is not None and math.isfinite(time) else math.inf
