"""An iterated local search on the sum of arrivals, for the min-sum proposal.

PyVRP minimises travel, which is not the sum of arrivals (the minimum-latency
objective: a target late in a long queue counts its whole wait). This search starts
from a plan (PyVRP's, improved by `fleet.consensus.improve`) and works on the sum
itself, with moves the baseline's relocations lack:

* relocate one target anywhere (its own queue or another's);
* swap two targets (in one queue or two);
* exchange two queues' tails (2-opt*), and reverse a stretch of one queue (2-opt);

first improvement, each move kept only when it lowers the sum by more than a rounding
error; then rounds of ruin and recreate (a seeded 30 % of the targets taken out and put
back, each where it adds least to the sum), each followed by the same descent, the best
plan kept: 200 rounds up to 20 targets, 80 at 50, 40 from 100 on. Deterministic for a
seed: an iteration count, never a time limit. A route's sum is computed whole (queues
are short: a handful of targets a UAV), as `sum((len - i) * leg_i)`: each leg is
waited for by every target after it.

Pure: no I/O. The plan is only proposed: every UAV re-scores it
(`fleet.consensus.proposal`).
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence

from fleet.consensus.assignment import time_or_inf
from fleet.consensus.queues import Legs, Queues, Times, legs_of

__all__ = ["ROUNDS", "search_min_sum"]

#: Rounds of ruin and recreate after the first descent: ROUND_TARGETS / targets, within
#: ROUNDS and MAX_ROUNDS (a round's descent costs about the square of the targets).
ROUNDS = 40
MAX_ROUNDS = 200
ROUND_TARGETS = 4000
#: The share of the targets a ruin takes out (at least two): 15 % left some plans where
#: they were (docs/benchmarks.md, "The min-sum proposal's own search").
RUIN_SHARE = 0.3
#: A move must lower the sum by more than this (s): no move for rounding alone.
EPSILON = 1e-6


def search_min_sum(
    queues: Queues, times: Times, legs: Legs, *, rounds: int | None = None, seed: int = 1
) -> Queues:
    """`queues` with a lower sum of arrivals, or as they were (a new mapping); `rounds`
    of ruin and recreate (None: by the number of targets)."""
    search = _Search(times, legs)
    current = {uav: list(queues.get(uav, ())) for uav in search.uavs}
    search.descend(current)
    best = {uav: list(q) for uav, q in current.items()}
    best_cost = search.total(best)
    rng = random.Random(seed)
    targets = sorted(t for q in best.values() for t in q)
    if len(targets) < 2:
        return best
    ruin = max(2, round(RUIN_SHARE * len(targets)))
    if rounds is None:
        rounds = max(ROUNDS, min(MAX_ROUNDS, ROUND_TARGETS // len(targets)))
    for _ in range(rounds):
        trial = {uav: list(q) for uav, q in best.items()}
        removed = rng.sample(targets, ruin)
        gone = set(removed)
        for uav in trial:
            trial[uav] = [t for t in trial[uav] if t not in gone]
        for target in removed:
            search.insert_cheapest(trial, target)
        search.descend(trial)
        cost = search.total(trial)
        if cost < best_cost - EPSILON:
            best, best_cost = trial, cost
    return best


class _Search:
    def __init__(self, times: Times, legs: Legs) -> None:
        self.uavs = sorted(times)
        self.rows = {uav: [time_or_inf(t) for t in times[uav]] for uav in self.uavs}
        self.legs = {uav: legs_of(legs, uav) for uav in self.uavs}

    def cost(self, uav: int, route: Sequence[int]) -> float:
        """The sum of arrivals along `route` (inf where a leg is not flown)."""
        if not route:
            return 0.0
        table = self.legs[uav]
        count = len(route)
        total = count * self.rows[uav][route[0]]
        for i in range(1, count):
            total += (count - i) * table[route[i - 1]][route[i]]
        return total if math.isfinite(total) else math.inf

    def total(self, plan: Queues) -> float:
        return sum(self.cost(uav, plan[uav]) for uav in self.uavs)

    def insert_cheapest(self, plan: Queues, target: int) -> None:
        """Put `target` where it adds least to the sum (the lowest UAV, place on ties)."""
        best: tuple[float, int, int] | None = None
        for uav in self.uavs:
            route = plan[uav]
            base = self.cost(uav, route)
            for place in range(len(route) + 1):
                added = self.cost(uav, [*route[:place], target, *route[place:]]) - base
                if best is None or added < best[0]:
                    best = (added, uav, place)
        assert best is not None
        _, uav, place = best
        plan[uav].insert(place, target)

    def descend(self, plan: Queues) -> None:
        """Apply improving moves until none is left (each pass bounded by the moves)."""
        costs = {uav: self.cost(uav, plan[uav]) for uav in self.uavs}
        improved = True
        while improved:
            improved = False
            for move in (self._relocate, self._swap, self._tails, self._reverse):
                if move(plan, costs):
                    improved = True

    def _better(self, plan: Queues, costs: dict[int, float], changes: dict[int, list[int]]) -> bool:
        before = sum(costs[uav] for uav in changes)
        after = {uav: self.cost(uav, route) for uav, route in changes.items()}
        if sum(after.values()) < before - EPSILON:
            for uav, route in changes.items():
                plan[uav] = route
                costs[uav] = after[uav]
            return True
        return False

    def _relocate(self, plan: Queues, costs: dict[int, float]) -> bool:
        moved = False
        for a in self.uavs:
            i = 0
            while i < len(plan[a]):
                target = plan[a][i]
                left = [*plan[a][:i], *plan[a][i + 1 :]]
                done = False
                for b in self.uavs:
                    base = left if b == a else plan[b]
                    for place in range(len(base) + 1):
                        if b == a and place == i:
                            continue
                        route = [*base[:place], target, *base[place:]]
                        changes = {a: route} if b == a else {a: left, b: route}
                        if self._better(plan, costs, changes):
                            done = moved = True
                            break
                    if done:
                        break
                if not done:
                    i += 1
        return moved

    def _swap(self, plan: Queues, costs: dict[int, float]) -> bool:
        moved = False
        for ai, a in enumerate(self.uavs):
            for b in self.uavs[ai:]:
                for i in range(len(plan[a])):
                    for j in range(i + 1 if a == b else 0, len(plan[b])):
                        ra, rb = list(plan[a]), list(plan[b]) if a != b else None
                        if rb is None:
                            ra[i], ra[j] = ra[j], ra[i]
                            changes = {a: ra}
                        else:
                            ra[i], rb[j] = plan[b][j], plan[a][i]
                            changes = {a: ra, b: rb}
                        if self._better(plan, costs, changes):
                            moved = True
        return moved

    def _tails(self, plan: Queues, costs: dict[int, float]) -> bool:
        moved = False
        for ai, a in enumerate(self.uavs):
            for b in self.uavs[ai + 1 :]:
                for i in range(len(plan[a]) + 1):
                    for j in range(len(plan[b]) + 1):
                        if i == len(plan[a]) and j == len(plan[b]):
                            continue
                        ra = [*plan[a][:i], *plan[b][j:]]
                        rb = [*plan[b][:j], *plan[a][i:]]
                        if self._better(plan, costs, {a: ra, b: rb}):
                            moved = True
        return moved

    def _reverse(self, plan: Queues, costs: dict[int, float]) -> bool:
        moved = False
        for a in self.uavs:
            for i in range(len(plan[a])):
                for j in range(i + 2, len(plan[a]) + 1):
                    route = plan[a]
                    changed = [*route[:i], *reversed(route[i:j]), *route[j:]]
                    if self._better(plan, costs, {a: changed}):
                        moved = True
        return moved
