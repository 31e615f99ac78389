"""A tightening bound on the last arrival, for `min-max` (after `fleet.consensus.makespan`).

The relocations and the longest-queue moves only accept a move that shortens the plan
as it is, so they stall where a better plan needs work passed along a chain of queues
(the longest gives a target to a middle one, which gives one to an idle UAV far away).
So this search works the way a routing solver's route-duration bisection does: it sets
a bound below the plan's last arrival and looks for a plan whose every queue ends
within it, minimising

    sum over queues of (end + WEIGHT x max(end - bound, 0))

(a queue's end: when its UAV reaches its last target). Over the bound a queue costs
WEIGHT times its excess, so any queue over gives work away; within it the least flying
wins, which leaves room for the next bound. Found, the bound is lowered; not, it is
raised halfway back. At each bound:

* a local search (first improvement, targets in increasing index, each against its
  `NEAR` nearest targets and the starts of its `NEAR_UAVS` nearest UAVs): a target
  moved after or before another, two targets exchanged, two queues' tails exchanged
  (2-opt*), a stretch of one queue reversed (2-opt);
* then rounds of ruin and recreate while some queue is over the bound: a target of a
  queue over it and up to `RUIN_MAX` - 1 of its nearest removed, each put back where it
  adds the least cost (the first, the seed, in any queue but its own: put back where it
  adds the least over every queue, it most often went back where it was and the round
  rebuilt the plan it started from), the local search again on the queues changed; a
  round's plan is kept if its cost is at most `ACCEPT` above the current one (a
  threshold that falls to 0 over the rounds, so that the search can cross a flat
  stretch).

Up to `REGRET_UP_TO` (UAV, target) pairs, the search runs from the plan given and from
each distinct plan built afresh by regret insertion under a few bounds well below its
last arrival (each target in turn where its regret is the largest: what the next-best
queues' costs exceed the best's by), each run with `START_BUDGET` moves and its own
seed; then the `CONTINUED` lowest ends are each searched again, from where they ended,
with `CONTINUE_BUDGET` moves and a seed of their own, and the shortest plan is kept (the
first start's among equals). The plan given is often a poor basin, and where a run ends
depends on the basin it starts in far more than on how long it runs there; among the
best few basins, which one a second run lowers most differs from instance to instance
(the benchmark's 20 x 100 instances: docs/benchmarks.md).

Deterministic: a fixed seed (Python's Mersenne Twister, the same on every machine), a
fixed order, and at most `BUDGET` moves tried from one start, `START_BUDGET` from each of
several and `CONTINUE_BUDGET` in each second run (the plan never depends on the
machine's speed). Every queue is timed in its own UAV's legs (`legs_of`). Pure: no
I/O.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
from collections.abc import Iterable, Sequence

from fleet.consensus.assignment import time_or_inf
from fleet.consensus.queues import Legs, Queues, Rows, Times, leg_count, legs_of, reference_legs

#: A queue's cost per second over the bound (per second within it: 1).
WEIGHT = 100.0
#: Each target's nearest targets, and nearest UAVs, its moves are tried against.
NEAR = 10
NEAR_UAVS = 5
#: Bounds tried at most, and the first one's distance below the last arrival (relative;
#: halved each time a bound is not met).
STEPS = 10
FIRST_GAP = 0.05
#: A bound closer than this below the last arrival is not tried (relative): the search
#: then ends, its rounds spent where they can gain something.
MIN_GAP = 0.002
#: Ruin-and-recreate rounds per bound, targets removed per round at most, and the
#: threshold a round's plan is kept within (relative, falling to 0 over the rounds).
ROUNDS = 60
RUIN_MAX = 8
ACCEPT = 0.01
#: Moves and insertion places tried at most in a search from one start, and from each
#: of several starts.
BUDGET = 300_000
START_BUDGET = 30_000
#: The lowest ends of the several starts searched again, with this many moves each.
CONTINUED = 2
CONTINUE_BUDGET = 45_000
#: Instances up to this many (UAV, target) pairs get the regret-insertion starts, at
#: these bounds (relative to the plan's last arrival) and regrets (2: the second-best
#: queue's cost less the best's; 3: plus the third's less the best's): beyond, they
#: cost more than the search (each is T x T x the queues' length).
REGRET_UP_TO = 2_000
REGRET_STARTS = ((0.75, 2), (0.80, 2), (0.85, 2), (0.75, 3), (0.80, 3), (0.85, 3))
#: A move must lower the cost by more than this (relative): no move for rounding alone.
EPSILON = 1e-9
#: The seed of the rounds' choices.
SEED = 35


def tighten(queues: Queues, times: Times, legs: Legs) -> Queues:
    """`queues` with the last arrival lowered by the tightening bound (a new mapping; the
    input is left as it was)."""
    search = _Search(queues, times, legs)
    if len(search.uavs) < 2 or len(search.targets) < 2:
        return {uav: list(q) for uav, q in queues.items()}
    starts = [search.snapshot()]
    if len(search.uavs) * search.count <= REGRET_UP_TO:
        span = search.span()
        for share, regret in REGRET_STARTS:
            if search.build(span * share, regret):
                search.descend(search.targets)
                if search.routes not in starts:
                    starts.append(search.snapshot())
    if len(starts) == 1:
        best = search.bisect(starts[0])
    else:
        # From every start in turn, each with its own share of moves and its own seed:
        # where the search ends depends on the basin it starts in much more than on how
        # long it runs there, so several short runs beat one long one. Then the
        # `CONTINUED` lowest ends are each searched again with `CONTINUE_BUDGET` moves
        # and a seed of their own: which of them ends lowest differs from instance to
        # instance.
        ends = [
            _run(search, start, START_BUDGET, SEED + index) for index, start in enumerate(starts)
        ]
        ranked = sorted(range(len(ends)), key=lambda index: (ends[index][0], index))
        for rank, index in enumerate(ranked[:CONTINUED]):
            seed = SEED + len(starts) + rank
            again = _run(search, ends[index][1], CONTINUE_BUDGET, seed)
            if again[0] < ends[index][0]:
                ends[index] = again
        best = ends[min(range(len(ends)), key=lambda index: (ends[index][0], index))][1]
    return {uav: list(best[k][1:]) for k, uav in enumerate(search.uavs)}


def _run(
    search: _Search, start: list[list[int]], budget: int, seed: int
) -> tuple[float, list[list[int]]]:
    """The tightening bound from `start` with `budget` moves and the choices of `seed`:
    the last arrival it ends at, and its plan."""
    search.tried = 0
    search.limit = budget
    search.rng = random.Random(seed)
    plan = search.bisect(start)
    search.restore(plan)
    return search.span(), plan


class _Ext(dict[int, Sequence[float]]):
    """One UAV's rows: its own start's (its approach times) and its legs' (read from its
    table when first asked, so that each UAV's own air legs are computed lazily)."""

    def __init__(self, rows: Rows, start: int, approach: list[float]) -> None:
        super().__init__()
        self.rows = rows
        self[start] = approach

    def __missing__(self, node: int) -> Sequence[float]:
        row = self[node] = self.rows[node]
        return row


class _Search:
    def __init__(self, queues: Queues, times: Times, legs: Legs) -> None:
        self.uavs = sorted(queues)
        self.count = count = leg_count(legs)
        # A route is [its UAV's start node, its targets...]; start nodes follow targets.
        self.ext = [
            _Ext(legs_of(legs, uav), count + k, [time_or_inf(t) for t in times[uav]])
            for k, uav in enumerate(self.uavs)
        ]
        shared = reference_legs(legs)
        self.targets = sorted(t for q in queues.values() for t in q)
        self.near = {
            t: [u for _, u in sorted((shared[t][u], u) for u in self.targets if u != t)][:NEAR]
            for t in self.targets
        }
        self.near_starts = {
            t: [
                count + k
                for _, k in sorted((self.ext[k][count + k][t], k) for k in range(len(self.uavs)))
            ][:NEAR_UAVS]
            for t in self.targets
        }
        # A UAV only ever queues a target it has an approach time to (queues.py).
        self.reach = [self.ext[k][count + k] for k in range(len(self.uavs))]
        self.routes = [[count + k, *queues[uav]] for k, uav in enumerate(self.uavs)]
        self.arrivals: list[list[float]] = [[] for _ in self.uavs]
        self.where: dict[int, tuple[int, int]] = {}
        self.bound = math.inf
        self.tried = 0
        self.limit = BUDGET
        self.changed: set[int] = set()
        self.rng = random.Random(SEED)
        for k in range(len(self.routes)):
            self._index(k)

    # -- bookkeeping

    def _index(self, k: int) -> None:
        route, ext = self.routes[k], self.ext[k]
        clock = 0.0
        out = [0.0]
        for a, b in itertools.pairwise(route):
            clock += ext[a][b]
            out.append(clock)
        self.arrivals[k] = out
        for i in range(1, len(route)):
            self.where[route[i]] = (k, i)

    def _set(self, changes: dict[int, list[int]]) -> None:
        for k, route in changes.items():
            self.routes[k] = route
            self._index(k)
            self.changed.add(k)

    def snapshot(self) -> list[list[int]]:
        return [list(r) for r in self.routes]

    def restore(self, routes: list[list[int]]) -> None:
        self.routes = [list(r) for r in routes]
        for k in range(len(self.routes)):
            self._index(k)

    def span(self) -> float:
        return max(a[-1] for a in self.arrivals)

    def cost_of(self, end: float) -> float:
        over = end - self.bound
        return end + WEIGHT * over if over > 0.0 else end

    def cost(self) -> float:
        return math.fsum(self.cost_of(a[-1]) for a in self.arrivals)

    def _end(self, k: int, route: Sequence[int]) -> float:
        ext = self.ext[k]
        clock = 0.0
        for a, b in itertools.pairwise(route):
            clock += ext[a][b]
        return clock

    # -- the bisection

    def bisect(self, start: list[list[int]]) -> list[list[int]]:
        self.restore(start)
        best, best_span = start, self.span()
        gap = FIRST_GAP
        for _ in range(STEPS):
            if self.tried >= self.limit or gap < MIN_GAP:
                break
            self.bound = best_span * (1.0 - gap)
            self.restore(best)
            self.descend(self.targets)
            current = self.cost()
            for round_ in range(ROUNDS):
                if self.tried >= self.limit or self.span() <= self.bound:
                    break
                kept = self.snapshot()
                if self.kick():
                    cost = self.cost()
                    if cost <= current * (1.0 + ACCEPT * (1.0 - round_ / ROUNDS)):
                        current = cost
                        if self.span() < best_span * (1.0 - EPSILON):
                            best, best_span = self.snapshot(), self.span()
                        continue
                self.restore(kept)
            if self.span() < best_span * (1.0 - EPSILON):
                best, best_span = self.snapshot(), self.span()
            if best_span > self.bound:
                gap *= 0.5
        return best

    def kick(self) -> bool:
        """One round of ruin and recreate, then the search on the queues changed; False
        if a target found no place (the plan is then left half made: restore it)."""
        rng = self.rng
        busy = [k for k in range(len(self.routes)) if len(self.routes[k]) > 1]
        over = [k for k in busy if self.arrivals[k][-1] > self.bound]
        pool = over or busy
        k = pool[rng.randrange(len(pool))]
        seed = self.routes[k][1 + rng.randrange(len(self.routes[k]) - 1)]
        size = rng.randint(1, RUIN_MAX)
        removed = [seed, *self.near[seed][: size - 1]]
        gone = set(removed)
        self.changed = set()
        for j, route in enumerate(self.routes):
            if any(t in gone for t in route[1:]):
                self._set({j: [t for t in route if t not in gone]})
        # The seed is put back anywhere but the queue it came from: its cheapest place
        # is most often where it was, and the round then rebuilds the plan it started
        # from (a start with an idle UAV spent every round so).
        if not self._insert(seed, avoid=k) and not self._insert(seed):
            return False
        for t in removed[1:]:
            if not self._insert(t):
                return False
        self.descend(t for j in sorted(self.changed) for t in self.routes[j][1:])
        return True

    def _insert(self, t: int, avoid: int | None = None) -> bool:
        """Put `t` where it adds the least cost (the lowest (queue, position) among
        equals), in any queue but `avoid`; False if no queue can take it."""
        best = (math.inf, 0, 0)
        for k in range(len(self.routes)):
            if k == avoid:
                continue
            delta, at = self._best_place(k, t)
            if delta < best[0]:
                best = (delta, k, at)
        if not math.isfinite(best[0]):
            return False
        _, k, at = best
        route = self.routes[k]
        self._set({k: [*route[:at], t, *route[at:]]})
        return True

    def build(self, bound: float, regret_of: int = 2) -> bool:
        """Every queue built afresh by regret insertion under `bound` (the regret: the
        sum over the `regret_of` - 1 next-best queues of their cost less the best's);
        False if some target found no place (the plan is then left half made)."""
        self.bound = bound
        self.restore([[self.count + k] for k in range(len(self.uavs))])
        left = set(self.targets)
        queues = range(len(self.routes))
        table = {t: [self._best_place(k, t) for k in queues] for t in sorted(left)}
        while left:
            choice: tuple[tuple[float, float, int], int, int, int] | None = None
            for t in sorted(left):
                row = table[t]
                # The `regret_of` cheapest queues (heapq: what sorting all would give).
                order = heapq.nsmallest(regret_of, queues, key=lambda k: (row[k][0], k))
                first = row[order[0]][0]
                if not math.isfinite(first):
                    continue
                regret = 0.0
                for rank in range(1, regret_of):
                    other = row[order[rank]][0] if len(order) > rank else math.inf
                    regret += other - first if math.isfinite(other) else math.inf
                key = (-regret, first, t)
                if choice is None or key < choice[0]:
                    choice = (key, t, order[0], row[order[0]][1])
            if choice is None:
                return False
            _, t, k, at = choice
            route = self.routes[k]
            self._set({k: [*route[:at], t, *route[at:]]})
            left.discard(t)
            for other in left:
                table[other][k] = self._best_place(k, other)
        return True

    def _best_place(self, k: int, t: int) -> tuple[float, int]:
        route, ext, end = self.routes[k], self.ext[k], self.arrivals[k][-1]
        old = self.cost_of(end)
        best = (math.inf, 0)
        if self.reach[k][t] == math.inf:
            return best
        self.tried += len(route)
        for at in range(1, len(route) + 1):
            before = route[at - 1]
            add = ext[before][t]
            if at < len(route):
                add += ext[t][route[at]] - ext[before][route[at]]
            delta = self.cost_of(end + add) - old
            if delta < best[0]:
                best = (delta, at)
        return best

    # -- the local search

    def descend(self, targets: Iterable[int]) -> None:
        """First improvement from each of `targets` in turn; a target whose queue a
        move changed is tried again."""
        pending = list(dict.fromkeys(targets))
        waiting = set(pending)
        index = 0
        while index < len(pending) and self.tried < self.limit:
            t = pending[index]
            index += 1
            waiting.discard(t)
            self.changed = set()
            if self._move(t):
                for k in sorted(self.changed):
                    for u in self.routes[k][1:]:
                        if u not in waiting:
                            waiting.add(u)
                            pending.append(u)

    def _move(self, t: int) -> bool:
        count = self.count
        for n in itertools.chain(self.near[t], self.near_starts[t]):
            ka, i = self.where[t]
            kb, j = (n - count, 0) if n >= count else self.where[n]
            if ka == kb:
                if self._within(ka, i, j):
                    return True
            elif self._between(ka, i, kb, j):
                return True
        return False

    def _within(self, k: int, i: int, j: int) -> bool:
        """`t` (at i) moved after or before the node at j, or the stretch between them
        reversed, in one queue (timed whole: queues are short)."""
        route = self.routes[k]
        t = route[i]
        without = route[:i] + route[i + 1 :]
        at = j if j < i else j - 1
        trials = [[*without[: at + 1], t, *without[at + 1 :]]]
        if at >= 1:
            trials.append([*without[:at], t, *without[at:]])
        low, high = min(i, j), max(i, j)
        if low >= 1:
            trials.append(route[: low + 1] + route[low + 1 : high + 1][::-1] + route[high + 1 :])
            trials.append(route[:low] + route[low : high + 1][::-1] + route[high + 1 :])
        old = self.cost_of(self.arrivals[k][-1])
        bar = old - EPSILON * max(1.0, old)
        for trial in trials:
            if trial == route:
                continue
            self.tried += 1
            if self.cost_of(self._end(k, trial)) < bar:
                self._set({k: trial})
                return True
        return False

    def _between(self, ka: int, i: int, kb: int, j: int) -> bool:
        """Moves between `t` (queue ka, position i) and the node at j of queue kb."""
        a, b = self.routes[ka], self.routes[kb]
        arr_a, arr_b = self.arrivals[ka], self.arrivals[kb]
        end_a, end_b = arr_a[-1], arr_b[-1]
        xa, xb = self.ext[ka], self.ext[kb]
        cost = self.cost_of
        t, n, p = a[i], b[j], a[i - 1]
        s = a[i + 1] if i + 1 < len(a) else None
        sn = b[j + 1] if j + 1 < len(b) else None
        old = cost(end_a) + cost(end_b)
        bar = old - EPSILON * max(1.0, old)
        takes = self.reach[kb][t] < math.inf
        removed = arr_a[i - 1] if s is None else end_a - xa[p][t] - xa[t][s] + xa[p][s]
        # t after n
        self.tried += 1
        added = xb[n][t] + (xb[t][sn] - xb[n][sn] if sn is not None else 0.0)
        if takes and cost(removed) + cost(end_b + added) < bar:
            self._set({ka: a[:i] + a[i + 1 :], kb: [*b[: j + 1], t, *b[j + 1 :]]})
            return True
        if j >= 1:
            pn = b[j - 1]
            # t before n
            self.tried += 1
            added = xb[pn][t] + xb[t][n] - xb[pn][n]
            if takes and cost(removed) + cost(end_b + added) < bar:
                self._set({ka: a[:i] + a[i + 1 :], kb: [*b[:j], t, *b[j:]]})
                return True
            # t and n exchanged
            self.tried += 1
            new_a = end_a - xa[p][t] + xa[p][n] + (xa[n][s] - xa[t][s] if s is not None else 0.0)
            new_b = (
                end_b - xb[pn][n] + xb[pn][t] + (xb[t][sn] - xb[n][sn] if sn is not None else 0.0)
            )
            if takes and self.reach[ka][n] < math.inf and cost(new_a) + cost(new_b) < bar:
                self._set({ka: [*a[:i], n, *a[i + 1 :]], kb: [*b[:j], t, *b[j + 1 :]]})
                return True
        # Tails exchanged, n then t: a tail is estimated in its own UAV's legs, and the
        # move timed exactly in the other's before it is made.
        self.tried += 1
        tail_a = end_a - arr_a[i - 1] - xa[p][t]
        new_b = arr_b[j] + xb[n][t] + tail_a
        new_a = arr_a[i - 1] + (xa[p][sn] + end_b - arr_b[j + 1] if sn is not None else 0.0)
        if cost(new_a) + cost(new_b) < bar and self._exchange(
            ka, a[:i] + b[j + 1 :], kb, b[: j + 1] + a[i:], bar
        ):
            return True
        # Tails exchanged, t then n's successor and n then t's.
        self.tried += 1
        new_a = arr_a[i] + (xa[t][sn] + end_b - arr_b[j + 1] if sn is not None else 0.0)
        new_b = arr_b[j] + (xb[n][s] + end_a - arr_a[i + 1] if s is not None else 0.0)
        return cost(new_a) + cost(new_b) < bar and self._exchange(
            ka, a[: i + 1] + b[j + 1 :], kb, b[: j + 1] + a[i + 1 :], bar
        )

    def _exchange(self, ka: int, a: list[int], kb: int, b: list[int], bar: float) -> bool:
        reach_a, reach_b = self.reach[ka], self.reach[kb]
        if any(reach_a[t] == math.inf for t in a[1:]) or any(reach_b[t] == math.inf for t in b[1:]):
            return False
        if self.cost_of(self._end(ka, a)) + self.cost_of(self._end(kb, b)) < bar:
            self._set({ka: a, kb: b})
            return True
        return False
