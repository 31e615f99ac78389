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

import heapq
import itertools
import math
from collections.abc import Callable, Sequence

from fleet.consensus.assignment import time_or_inf
from fleet.consensus.queues import Legs, Queues, Times, leg_count, legs_of, reference_legs
from fleet.mission.objective import Objective

#: Passes over every target at most (a pass with no improvement ends the search).
MAX_PASSES = 8
#: How many nearest targets, and best-placed UAVs, a target's new places are next to.
NEIGHBOURS = 8
#: A move must improve the key by more than this (relative): no move for rounding alone.
EPSILON = 1e-9


def improve(queues: Queues, times: Times, legs: Legs, objective: Objective) -> Queues:
    """`queues` improved for `objective` (a new mapping; the input is left as it was)."""
    search = _Search({uav: list(q) for uav, q in queues.items()}, times, legs, objective)
    for _ in range(MAX_PASSES):
        if not search.one_pass():
            break
    return search.queues


class _Search:
    def __init__(self, queues: Queues, times: Times, legs: Legs, objective: Objective) -> None:
        self.queues = queues
        self.min_max = objective is Objective.MIN_MAX
        self.uavs = sorted(queues)
        # Each UAV's own table (fleet.consensus.legs.AirLegs), or the one they share.
        self.legs = {uav: legs_of(legs, uav) for uav in self.uavs}
        self.rows = {uav: [time_or_inf(t) for t in times[uav]] for uav in self.uavs}
        count = leg_count(legs)
        shared = reference_legs(legs)
        # Sorting (leg, index) pairs in C: the nearest first, ties by index.
        self.near = [
            [j for _, j in sorted(zip(shared[i], range(count), strict=True)) if j != i][:NEIGHBOURS]
            for i in range(count)
        ]
        self.best_uavs = [
            heapq.nsmallest(
                NEIGHBOURS,
                (uav for uav in self.uavs if self.rows[uav][t] < math.inf),
                key=_by_time(self.rows, t),
            )
            for t in range(count)
        ]
        self.arrivals = {uav: self._arrivals(uav, q) for uav, q in queues.items()}
        self.cost = {uav: _sum_end(a) for uav, a in self.arrivals.items()}
        self.position: dict[int, tuple[int, int]] = {}
        for uav in self.uavs:
            self._place_queue(uav)
        self._refresh()

    def _arrivals(self, uav: int, queue: Sequence[int]) -> list[float]:
        out: list[float] = []
        if queue:
            clock = self.rows[uav][queue[0]]
            out.append(clock)
            legs = self.legs[uav]
            for previous, target in itertools.pairwise(queue):
                clock += legs[previous][target]
                out.append(clock)
        return out

    def _place_queue(self, uav: int) -> None:
        for i, t in enumerate(self.queues[uav]):
            self.position[t] = (uav, i)

    def _refresh(self) -> None:
        self.total = math.fsum(c[0] for c in self.cost.values())
        self.top = heapq.nlargest(3, ((c[1], uav) for uav, c in self.cost.items()))

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
        for target in sorted(self.position):
            if self._relocate(target, self.position[target][0]):
                moved = True
        return moved

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
            places.add((uav, len(self.queues[uav]) - (uav == home)))
        return sorted(p for p in places if self.rows[p[0]][target] < math.inf)

    def _removal(self, home: int, start: int) -> tuple[float, float] | None:
        """(sum, end) of `home`'s queue without its target at `start`; None if the next
        target cannot head it."""
        queue, arrivals, legs = self.queues[home], self.arrivals[home], self.legs[home]
        last = len(queue) - 1
        total, end = self.cost[home]
        if last == 0:
            return 0.0, 0.0
        if start == last:
            return total - arrivals[last], arrivals[last - 1]
        if start == 0:
            moved = self.rows[home][queue[1]]
            if moved == math.inf:
                return None
        else:
            moved = arrivals[start - 1] + legs[queue[start - 1]][queue[start + 1]]
        shift = moved - arrivals[start + 1]
        return total - arrivals[start] + (last - start) * shift, end + shift

    def _insertion(self, uav: int, index: int, target: int) -> tuple[float, float]:
        """(sum, end) of `uav`'s queue with `target` inserted at `index`."""
        queue, arrivals, legs = self.queues[uav], self.arrivals[uav], self.legs[uav]
        total, end = self.cost[uav]
        if index == 0:
            at = self.rows[uav][target]
        else:
            at = arrivals[index - 1] + legs[queue[index - 1]][target]
        if index == len(queue):
            return total + at, at
        shift = at + legs[target][queue[index]] - arrivals[index]
        return total + at + (len(queue) - index) * shift, end + shift

    def _relocate(self, target: int, home: int) -> bool:
        start = self.position[target][1]
        removed = self._removal(home, start)
        if removed is None:
            return False
        home_queue = self.queues[home]
        without = home_queue[:start] + home_queue[start + 1 :]
        first, second = self._key(self.total, self.top[0][0] if self.top else 0.0)
        # A move must gain more than rounding: EPSILON of the key's size.
        first_bar = first - EPSILON * max(1.0, abs(first))
        first_tie = first + EPSILON * max(1.0, abs(first))
        second_bar = second - EPSILON * max(1.0, abs(second))
        min_max = self.min_max
        for uav, index in self._places(target, home):
            if uav == home:
                if index == start or index > len(without):
                    continue  # where it is now
                trial = [*without[:index], target, *without[index:]]
                if self.rows[uav][trial[0]] == math.inf:
                    continue
                new_cost = _sum_end(self._arrivals(uav, trial))
                total = self.total - self.cost[home][0] + new_cost[0]
                makespan = max(self._others_end(home, home), new_cost[1])
            else:
                if index > len(self.queues[uav]):
                    continue
                new_cost = self._insertion(uav, index, target)
                total = self.total - self.cost[home][0] - self.cost[uav][0]
                total += removed[0] + new_cost[0]
                makespan = max(self._others_end(home, uav), removed[1], new_cost[1])
            a, b = (makespan, total) if min_max else (total, makespan)
            if a < first_bar or (a <= first_tie and b < second_bar):
                self.queues[home] = without
                queue = self.queues[uav]
                self.queues[uav] = [*queue[:index], target, *queue[index:]]
                for changed in {home, uav}:
                    self.arrivals[changed] = self._arrivals(changed, self.queues[changed])
                    self.cost[changed] = _sum_end(self.arrivals[changed])
                    self._place_queue(changed)
                self._refresh()
                return True
        return False


def _sum_end(arrivals: Sequence[float]) -> tuple[float, float]:
    return (math.fsum(arrivals), arrivals[-1]) if arrivals else (0.0, 0.0)


def _by_time(rows: dict[int, list[float]], t: int) -> Callable[[int], tuple[float, int]]:
    return lambda uav: (rows[uav][t], uav)
