"""Moves that shorten the longest queue, for `min-max` (after `fleet.consensus.improve`).

Relocating one target at a time to a place near its neighbours (`improve`) stalls on
the last arrival: the longest queue's targets often have no better place *nearby*, and
a better plan needs a target moved far, two targets exchanged, or two queues' tails
swapped. So, after the relocations, this search works on the queue that ends last (the
lowest Piccolo ID among equals) and tries, in this order, each in increasing (position,
Piccolo ID, position) order, the first that lowers the key (last arrival, total of
arrivals) taken:

* **relocate anywhere**: one of its targets to any place in any queue;
* **exchange**: one of its targets with one of another queue's (each takes the other's
  place);
* **tails**: its tail after some target swapped with another queue's tail after some
  target (the 2-opt* move of vehicle routing), either tail possibly empty;
* **reverse**: a stretch of its own queue flown the other way (2-opt).

At most `MAX_MOVES` moves (the plan never depends on the machine's speed); a round that
finds no move ends the search. Every queue is timed in its own UAV's legs (`legs_of`).
Pure: no I/O.
"""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Iterator, Sequence

from fleet.consensus.assignment import time_or_inf
from fleet.consensus.queues import Legs, Queues, Rows, Times, legs_of, reference_legs

#: Moves at most, per target (a search of T targets makes at most this many x T).
MOVES_PER_TARGET = 4
#: Moves tried (each a queue or two timed) at most in a search: 50 x 200 stays within
#: about a hundred milliseconds with each UAV's own legs.
MOVES_TRIED = 5_000
#: A move must lower the key by more than this (relative): no move for rounding alone.
EPSILON = 1e-9


def shorten_longest(queues: Queues, times: Times, legs: Legs) -> Queues:
    """`queues` with the longest queue shortened while some move lowers (last arrival,
    total) (a new mapping; the input is left as it was)."""
    search = _Longest({uav: list(q) for uav, q in queues.items()}, times, legs)
    count = sum(len(q) for q in queues.values())
    for _ in range(MOVES_PER_TARGET * max(count, 1)):
        if search.tried >= MOVES_TRIED or not search.one_move():
            break
    return search.queues


class _Longest:
    def __init__(self, queues: Queues, times: Times, legs: Legs) -> None:
        self.queues = queues
        self.uavs = sorted(queues)
        self.rows = {uav: [time_or_inf(t) for t in times[uav]] for uav in self.uavs}
        self.legs: dict[int, Rows] = {uav: legs_of(legs, uav) for uav in self.uavs}
        self.ends = {uav: self._end_total(uav, q) for uav, q in queues.items()}
        self.tried = 0

    def _end_total(self, uav: int, queue: Sequence[int]) -> tuple[float, float]:
        """(last arrival, total of arrivals) of `uav` flying `queue`; inf if unflyable."""
        if not queue:
            return 0.0, 0.0
        clock = self.rows[uav][queue[0]]
        total = clock
        legs = self.legs[uav]
        for previous, target in itertools.pairwise(queue):
            clock += legs[previous][target]
            total += clock
        return clock, total

    def _key(self, ends: dict[int, tuple[float, float]]) -> tuple[float, float]:
        return max(e for e, _ in ends.values()), math.fsum(t for _, t in ends.values())

    def one_move(self) -> bool:
        """Make the first move that lowers the key; False if none does."""
        if not self.ends:
            return False
        worst = max(self.uavs, key=lambda uav: (self.ends[uav][0], -uav))
        key = self._key(self.ends)
        bar = (key[0] - EPSILON * max(1.0, key[0]), key[1] - EPSILON * max(1.0, key[1]))
        tie = key[0] + EPSILON * max(1.0, key[0])
        for change in self._moves(worst):
            self.tried += 1
            if self.tried > MOVES_TRIED:
                return False
            ends = dict(self.ends)
            for uav, queue in change.items():
                ends[uav] = self._end_total(uav, queue)
            end, total = self._key(ends)
            if end < bar[0] or (end <= tie and total < bar[1]):
                for uav, queue in change.items():
                    self.queues[uav] = queue
                self.ends = ends
                return True
        return False

    def _moves(self, worst: int) -> Iterator[dict[int, list[int]]]:
        """The moves on the longest queue `worst`, each as the queues it changes."""
        own = self.queues[worst]
        others = [uav for uav in self.uavs if uav != worst]
        for i, target in enumerate(own):  # relocate anywhere
            without = own[:i] + own[i + 1 :]
            if without and self.rows[worst][without[0]] == math.inf:
                continue
            for uav in others:
                if self.rows[uav][target] == math.inf:
                    continue
                queue = self.queues[uav]
                for at in range(len(queue) + 1):
                    yield {worst: without, uav: [*queue[:at], target, *queue[at:]]}
        for i, target in enumerate(own):  # exchange
            for uav in others:
                if self.rows[uav][target] == math.inf:
                    continue
                queue = self.queues[uav]
                for j, other in enumerate(queue):
                    if self.rows[worst][other] == math.inf:
                        continue
                    yield {
                        worst: [*own[:i], other, *own[i + 1 :]],
                        uav: [*queue[:j], target, *queue[j + 1 :]],
                    }
        for i in range(len(own)):  # tails: own[i:] and queue[j:] swapped
            for uav in others:
                queue = self.queues[uav]
                for j in range(len(queue) + 1):
                    if (i, j) == (0, 0):
                        continue  # the two whole queues swapped: not a shorter plan
                    # A UAV only ever queues targets it has an approach time to.
                    if any(self.rows[worst][t] == math.inf for t in queue[j:]):
                        continue
                    if any(self.rows[uav][t] == math.inf for t in own[i:]):
                        continue
                    yield {worst: own[:i] + queue[j:], uav: queue[:j] + own[i:]}
        for i in range(len(own) - 1):  # reverse own[i..k]
            for k in range(i + 1, len(own)):
                yield {worst: own[:i] + own[i : k + 1][::-1] + own[k + 1 :]}


#: Bisection steps on the bound, and ruin-and-recreate rounds per step; at most
#: `RECREATE_BUDGET` insertion places tried in all (so that 50 x 200 stays bounded).
BISECTION_STEPS = 8
ROUNDS_PER_STEP = 60
RECREATE_BUDGET = 120_000
#: Targets removed per round at most.
RUIN_MAX = 10
#: The seed of the rounds' choices: a fixed one (Python's Mersenne Twister, the same on
#: every machine), so that every UAV makes the same choices.
RUIN_SEED = 35


def ruin_and_recreate(queues: Queues, times: Times, legs: Legs) -> Queues:
    """`queues` with the last arrival lowered by a bisection on a bound of it: at each
    bound, rounds of ruin and recreate (remove a target of a queue over the bound and
    its nearest targets, wherever they are; put each back where it adds the least time
    over the bound, then the least flying) look for a plan with every queue within the
    bound and the least flying (the sum of the queues' ends): found, the bound is
    lowered; not, raised. The way a routing solver's route-duration bisection works.
    Deterministic: a fixed seed and fixed budgets."""
    search = _Bisection(queues, times, legs)
    return search.run()


class _Bisection:
    def __init__(self, queues: Queues, times: Times, legs: Legs) -> None:
        self.uavs = sorted(queues)
        self.rows = {uav: [time_or_inf(t) for t in times[uav]] for uav in self.uavs}
        self.tables: dict[int, Rows] = {uav: legs_of(legs, uav) for uav in self.uavs}
        shared = reference_legs(legs)
        self.start = {uav: list(queues[uav]) for uav in self.uavs}
        self.targets = sorted(t for q in queues.values() for t in q)
        # Each target's nearest (by the shared table, then index): removed with it.
        self.near = {
            t: [u for _, u in sorted((shared[t][u], u) for u in self.targets if u != t)][:RUIN_MAX]
            for t in self.targets
        }
        self.rng = random.Random(RUIN_SEED)
        self.spent = 0

    def ends(self, plan: dict[int, list[int]]) -> dict[int, float]:
        return {uav: _end(q, self.rows[uav], self.tables[uav]) for uav, q in plan.items()}

    def run(self) -> Queues:
        best = self.start
        if len(self.uavs) < 2 or len(self.targets) < 2:
            return best
        high = max(self.ends(best).values())
        # No plan ends before its hardest target is reached by its nearest UAV.
        low = max(min(self.rows[u][t] for u in self.uavs) for t in self.targets)
        plan = best
        for _ in range(BISECTION_STEPS):
            if self.spent >= RECREATE_BUDGET or high - low <= 1e-6 * high:
                break
            bound = 0.5 * (low + high)
            plan = self.within(plan, bound)
            span = max(self.ends(plan).values())
            if span <= bound:
                best, high = plan, span
            else:
                low = bound
                plan = best
        return best

    def key(self, plan: dict[int, list[int]], bound: float) -> tuple[float, float]:
        ends = self.ends(plan).values()
        return math.fsum(max(e - bound, 0.0) for e in ends), math.fsum(ends)

    def within(self, start: dict[int, list[int]], bound: float) -> dict[int, list[int]]:
        """The plan with the least (time over `bound`, flying) the rounds found."""
        rng = self.rng
        current = {uav: list(q) for uav, q in start.items()}
        current_key = self.key(current, bound)
        for _ in range(ROUNDS_PER_STEP):
            if current_key[0] == 0.0 and _ > ROUNDS_PER_STEP // 2:
                break
            if self.spent >= RECREATE_BUDGET:
                break
            ends = self.ends(current)
            over = [uav for uav in self.uavs if ends[uav] > bound and current[uav]]
            pool = over or [uav for uav in self.uavs if current[uav]]
            uav = pool[rng.randrange(len(pool))]
            seed = current[uav][rng.randrange(len(current[uav]))]
            size = rng.randint(1, min(RUIN_MAX, len(self.targets) - 1))
            removed = [seed, *self.near[seed][: size - 1]]
            plan = {u: [t for t in q if t not in removed] for u, q in current.items()}
            if plan[uav] and self.rows[uav][plan[uav][0]] == math.inf:
                continue
            rng.shuffle(removed)
            for target in removed:
                placed = self.place(plan, target, bound)
                if placed is None:
                    break
                plan[placed[0]].insert(placed[1], target)
            else:
                key = self.key(plan, bound)
                if key <= current_key:
                    current, current_key = plan, key
        return current

    def place(
        self, plan: dict[int, list[int]], target: int, bound: float
    ) -> tuple[int, int] | None:
        """Where `target` adds the least (time over `bound`, flying): the lowest
        (Piccolo ID, position) among equals; None if no UAV can take it."""
        best: tuple[float, float, int, int] | None = None
        for uav in self.uavs:
            row, table, queue = self.rows[uav], self.tables[uav], plan[uav]
            if row[target] == math.inf:
                continue
            a = _arrivals(queue, row, table)
            end = a[-1] if a else 0.0
            over = max(end - bound, 0.0)
            self.spent += len(queue) + 1
            for at in range(len(queue) + 1):
                if at == 0:
                    if queue and row[queue[0]] == math.inf:
                        continue
                    arrive = row[target]
                else:
                    arrive = a[at - 1] + table[queue[at - 1]][target]
                if at == len(queue):
                    new_end = arrive
                else:
                    new_end = end + arrive + table[target][queue[at]] - a[at]
                candidate = (max(new_end - bound, 0.0) - over, new_end - end, uav, at)
                if best is None or candidate < best:
                    best = candidate
        return None if best is None else (best[2], best[3])


def _arrivals(queue: Sequence[int], row: Sequence[float], table: Rows) -> list[float]:
    out: list[float] = []
    if queue:
        clock = row[queue[0]]
        out.append(clock)
        for previous, target in itertools.pairwise(queue):
            clock += table[previous][target]
            out.append(clock)
    return out


def _end(queue: Sequence[int], row: Sequence[float], table: Rows) -> float:
    a = _arrivals(queue, row, table)
    return a[-1] if a else 0.0
