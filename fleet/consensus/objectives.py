"""The plan for a mission's objective: `plan_queues`, what every UAV runs.

* No more targets than UAVs: an assignment problem, one target each, solved exactly.
  `min-sum` by the Hungarian method (`hungarian`) on the approach times: the most
  targets matched, then the least total. `min-max` by the bottleneck assignment: the
  least threshold under which as many targets can be matched (a binary search over the
  distinct times, each step a bipartite matching), then the least total under it.
  `greedy` is the thesis's rule.
* More targets than UAVs (or a reachable target no matching could give anyone): the
  greedy queues (`fleet.consensus.queues.greedy_queues`), then, for `min-sum` and
  `min-max`, improved by relocating one target at a time (`fleet.consensus.improve`): a
  deterministic local search with a bounded number of passes, whose measured gap to the
  optimum is in docs/benchmarks.md. `min-max` then goes on with the moves on the longest
  queue and a bisection by ruin and recreate (`fleet.consensus.makespan`), and a
  tightening bound on the last arrival (`fleet.consensus.tighten`), each bounded.

Deterministic: the input is read in increasing (Piccolo ID, target index) order, and
every choice among equals takes the first in that order. Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from fleet.consensus.assignment import time_or_inf
from fleet.consensus.digest import sha256
from fleet.consensus.improve import improve
from fleet.consensus.makespan import ruin_and_recreate, shorten_longest
from fleet.consensus.queues import (
    Legs,
    Orders,
    QueuePlan,
    Queues,
    Times,
    append_earliest,
    check_input,
    finish,
    greedy_queues,
    plan_clocks,
)
from fleet.consensus.tighten import tighten
from fleet.mission.objective import Objective

#: Instances up to this many (UAV, target) pairs get the min-max second start: beyond,
#: it would double the rule's time (50 x 200: over 100 ms).
SECOND_START_UP_TO = 2_000
#: Instances up to this many pairs get the min-max bisection by ruin and recreate
#: (fleet.consensus.makespan): beyond, with each UAV's own legs, the rows it asks for
#: cost about a second a decision at 50 x 200.
RUIN_UP_TO = 5_000

__all__ = ["bottleneck_assign", "hungarian", "min_sum_assign", "plan_digest", "plan_queues"]


def plan_queues(
    times: Times,
    legs: Legs,
    objective: Objective = Objective.GREEDY,
    orders: Orders | None = None,
) -> QueuePlan:
    """Every UAV's queue for `objective`; ValueError if a row has the wrong length.
    `orders`: each UAV's `row_order` of its times, where computed beforehand (the
    greedy's; the same plan either way)."""
    count = check_input(times, legs)
    uavs = sorted(times)
    if objective is Objective.GREEDY or count > len(uavs):
        queues = greedy_queues(times, legs, orders)
        if objective is Objective.GREEDY:
            return finish(queues, times, legs)
        best = improve(queues, times, legs, objective)
        ruin = len(uavs) * count <= RUIN_UP_TO
        if objective is Objective.MIN_MAX:
            if ruin:
                best = ruin_and_recreate(best, times, legs)
            best = shorten_longest(best, times, legs)
        if objective is Objective.MIN_MAX and len(uavs) * count <= SECOND_START_UP_TO:
            # The relocations alone stall on the last arrival; a second start, from the
            # min-sum plan, often ends lower. The better of the two by (last, total).
            other = improve(improve(queues, times, legs, Objective.MIN_SUM), times, legs, objective)
            other = shorten_longest(
                ruin_and_recreate(other, times, legs) if ruin else other, times, legs
            )
            best = min(best, other, key=lambda q: _last_total(q, times, legs))
        if objective is Objective.MIN_MAX:
            # The moves above stall where work must pass along a chain of queues: a
            # bound on the last arrival, tightened (fleet.consensus.tighten), then the
            # relocations for the total under it. The better of the two by (last, total).
            tightened = improve(tighten(best, times, legs), times, legs, objective)
            best = min(best, tightened, key=lambda q: _last_total(q, times, legs))
        return finish(best, times, legs)
    pairs = min_sum_assign(times, count) if objective is Objective.MIN_SUM else None
    if pairs is None:
        pairs = bottleneck_assign(times, count)
    heads: Queues = {uav: [pairs[uav]] if uav in pairs else [] for uav in uavs}
    # A target the matching left out although some UAV reaches it (its only reachers
    # were matched elsewhere) is queued behind them: every reachable target is served.
    left = [t for t in range(count) if t not in pairs.values()]
    append_earliest(heads, plan_clocks(heads, times, legs), left, times, legs)
    return finish(heads, times, legs)


def _last_total(queues: Queues, times: Times, legs: Legs) -> tuple[float, float]:
    plan = finish(queues, times, legs)
    return plan.makespan(), plan.total()


def min_sum_assign(times: Times, count: int) -> dict[int, int]:
    """One target each, the most targets matched, then the least total approach time."""
    return _assign(_clean(times), range(count), math.inf)


def bottleneck_assign(times: Times, count: int) -> dict[int, int]:
    """One target each, the most targets matched, then the least largest approach time,
    then the least total under that largest."""
    rows = _clean(times)
    uavs = sorted(rows)
    targets = list(range(count))
    edges = [[u for u, uav in enumerate(uavs) if rows[uav][t] < math.inf] for t in targets]
    size = _matching_size(edges, len(uavs))
    distinct = sorted({rows[uav][t] for uav in uavs for t in targets} - {math.inf})
    low, high = 0, len(distinct) - 1
    while low < high:  # the least threshold that still matches `size` targets
        middle = (low + high) // 2
        limit = distinct[middle]
        under = [[u for u in row if rows[uavs[u]][t] <= limit] for t, row in enumerate(edges)]
        if _matching_size(under, len(uavs)) >= size:
            high = middle
        else:
            low = middle + 1
    return _assign(rows, targets, distinct[low] if distinct else math.inf)


def _clean(times: Times) -> dict[int, list[float]]:
    """Each UAV's times, +inf where it has no usable one, by increasing Piccolo ID."""
    return {uav: [time_or_inf(t) for t in times[uav]] for uav in sorted(times)}


def _assign(rows: dict[int, list[float]], targets: Sequence[int], limit: float) -> dict[int, int]:
    """The Hungarian method on the targets x UAVs, times above `limit` or unusable
    forbidden; the pairs with a forbidden cost are dropped."""
    uavs = list(rows)
    allowed_all = [[_allowed(rows[uav][t], limit) for uav in uavs] for t in targets]
    kept = [t for t, row in zip(targets, allowed_all, strict=True) if any(row)]
    allowed = [row for row in allowed_all if any(row)]
    if not kept:
        return {}
    scale = math.fsum(
        abs(rows[uav][t]) for r, t in enumerate(kept) for c, uav in enumerate(uavs) if allowed[r][c]
    )
    # Larger than any sum of allowed costs: the most allowed pairs come first.
    forbidden = (scale + 1.0) * 2.0 * (len(kept) + 1)
    cost = [
        [rows[uav][t] if allowed[r][c] else forbidden for c, uav in enumerate(uavs)]
        for r, t in enumerate(kept)
    ]
    columns = hungarian(cost)
    return {uavs[column]: kept[row] for row, column in enumerate(columns) if allowed[row][column]}


def hungarian(cost: Sequence[Sequence[float]]) -> list[int]:
    """The column of each row in a least-total assignment of rows to distinct columns
    (rows <= columns; the shortest augmenting path form of the Hungarian method, O(n^2 m)).

    Deterministic: the lowest column index wins every tie in the scans.
    """
    n = len(cost)
    m = len(cost[0]) if n else 0
    if n > m:
        raise ValueError(f"{n} rows and {m} columns: rows must not outnumber columns")
    inf = math.inf
    u = [0.0] * (n + 1)
    v = [0.0] * (m + 1)
    owner = [0] * (m + 1)  # owner[j]: the row (1-based) matched to column j, 0 if none
    way = [0] * (m + 1)
    for i in range(1, n + 1):
        owner[0] = i
        j0 = 0
        slack = [inf] * (m + 1)
        used = [False] * (m + 1)
        while True:
            used[j0] = True
            i0 = owner[j0]
            delta = inf
            j1 = 0
            row = cost[i0 - 1]
            ui0 = u[i0]
            for j in range(1, m + 1):
                if not used[j]:
                    current = row[j - 1] - ui0 - v[j]
                    if current < slack[j]:
                        slack[j] = current
                        way[j] = j0
                    if slack[j] < delta:
                        delta = slack[j]
                        j1 = j
            for j in range(m + 1):
                if used[j]:
                    u[owner[j]] += delta
                    v[j] -= delta
                else:
                    slack[j] -= delta
            j0 = j1
            if owner[j0] == 0:
                break
        while j0:  # augment along the path found
            j1 = way[j0]
            owner[j0] = owner[j1]
            j0 = j1
    columns = [0] * n
    for j in range(1, m + 1):
        if owner[j]:
            columns[owner[j] - 1] = j - 1
    return columns


def _matching_size(edges: list[list[int]], columns: int) -> int:
    """The size of a maximum matching of rows to columns over `edges[row]` (Kuhn's
    augmenting paths, iterative so that 100 rows never recurse deep)."""
    owner = [-1] * columns
    size = 0
    for start in range(len(edges)):
        # Depth-first search for an augmenting path from `start`.
        seen = [False] * columns
        parent: dict[int, tuple[int, int]] = {}  # column -> (row, previous column)
        stack = [(start, -1)]
        found = -1
        while stack and found < 0:
            row, via = stack.pop()
            for column in edges[row]:
                if seen[column]:
                    continue
                seen[column] = True
                parent[column] = (row, via)
                if owner[column] < 0:
                    found = column
                    break
                stack.append((owner[column], column))
        if found < 0:
            continue
        column = found
        while column >= 0:  # flip the path
            row, via = parent[column]
            owner[column] = row
            column = via
        size += 1
    return size


def _allowed(time: float, limit: float) -> bool:
    return time < math.inf and time <= limit


_OBJECTIVE_VERSION = b"fleet.queues.objective/v1\x00"


def plan_digest(results_digest: str, objective: Objective) -> str:
    """The digest of a plan: the results' own for `greedy` (as before objectives
    existed), else the results' hashed with the objective, so that two plans of the
    same results under different objectives never share a digest."""
    if objective is Objective.GREEDY:
        return results_digest
    h = sha256(_OBJECTIVE_VERSION)
    h.update(objective.value.encode("ascii") + b"\x00" + results_digest.encode("ascii", "replace"))
    return h.hexdigest()[:16]
