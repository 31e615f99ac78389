"""Task queues: every reachable target in exactly one UAV's ordered queue.

Every UAV runs `plan_queues` on the same digested input (its teammates' approach times,
the mission's targets and objective) and reaches the same queues without a
coordinator. The input:

* `times[uav][t]`: UAV `uav`'s approach time (s) to target `t` from its own model,
  None (or NaN, or an infinity) where it has none. A UAV only ever queues a target it
  has a finite approach time to: its model says it can reach it.
* `legs[i][j]`: the time from target i to target j: one table for every UAV, or each
  UAV's own (`LegTables`: `fleet.consensus.legs.AirLegs`, timed at that UAV's airspeed
  in the wind its digested result carries, so identical on every UAV).

A queue's arrivals are cumulative: the first target at its approach time, each next one
a leg later. The objectives (`fleet.mission.objective.Objective`):

* `greedy`: the thesis's rule (`greedy_assign`: one target each, lowest (time, Piccolo
  ID, target index) first), then every target left is appended, one at a time, where it
  is reached earliest: the lowest (finishing time, Piccolo ID, target index) over every
  UAV's queue end and every target left. With no more targets than UAVs, and every
  target matched, it is exactly the thesis's assignment.
* `min-sum` and `min-max`: `fleet.consensus.objectives`.

Ties are broken by the total order (Piccolo ID, target index) everywhere, and the input
is read in increasing Piccolo ID order, so the plan does not depend on the order of the
mapping given. Pure: no I/O.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from fleet.consensus.assignment import greedy_assign, usable

Times = Mapping[int, Sequence[float | None]]
#: legs[i][j]: seconds from target i to target j.
Matrix = Sequence[Sequence[float]]


class Rows(Protocol):
    """legs[i][j], as the search reads it: a `Matrix`, or rows computed when first asked."""

    def __getitem__(self, i: int, /) -> Sequence[float]: ...


class LegTables(ABC):
    """Each UAV's own leg table, and the arrivals along a queue in it.

    `of(uav)[i][j]` is the pairwise time the search plans with; `arrivals` may time a
    queue more exactly (a leg's turn depends on the leg before it): what the plan
    reports and is scored by. Both must be functions of the digested input only.
    """

    @property
    @abstractmethod
    def count(self) -> int:
        """The number of targets."""

    @abstractmethod
    def of(self, uav: int) -> Rows:
        """UAV `uav`'s legs[i][j]."""

    @abstractmethod
    def reference(self) -> Matrix:
        """One table for every UAV: what a target's neighbours are found by."""

    @abstractmethod
    def arrivals(self, uav: int, first: float, queue: Sequence[int]) -> list[float]:
        """The arrival at each target of `uav`'s `queue`, the first at `first`."""


#: One table for every UAV, or each UAV's own.
Legs = Matrix | LegTables


def leg_count(legs: Legs) -> int:
    """The number of targets the legs are between."""
    return legs.count if isinstance(legs, LegTables) else len(legs)


def legs_of(legs: Legs, uav: int) -> Rows:
    """UAV `uav`'s table."""
    return legs.of(uav) if isinstance(legs, LegTables) else legs


def reference_legs(legs: Legs) -> Matrix:
    """The one table neighbourhoods are found by."""
    return legs.reference() if isinstance(legs, LegTables) else legs


def queue_arrivals(times: Times, legs: Legs, uav: int, queue: Sequence[int]) -> list[float]:
    """The arrivals along `uav`'s `queue`: what a plan reports and is scored by."""
    if isinstance(legs, LegTables):
        if not queue:
            return []
        first = times[uav][queue[0]]
        assert first is not None
        return legs.arrivals(uav, first, queue)
    return arrivals_of(times[uav], legs, queue)


Queues = dict[int, list[int]]
#: Each UAV's targets in the greedy's order (`fleet.consensus.assignment.row_order`).
Orders = Mapping[int, Sequence[int]]

#: Why a target is in no queue.
UNREACHABLE = "no UAV has an approach time to it"


@dataclass(frozen=True, slots=True)
class QueuePlan:
    """Every UAV's ordered queue of target indices (ascending Piccolo ID; an idle UAV's
    queue is empty), the predicted arrival (s from the start) at each queued target, and
    the targets in no queue (ascending), none of them reachable by any UAV."""

    queues: dict[int, tuple[int, ...]]
    arrivals: dict[int, tuple[float, ...]]
    unassigned: tuple[int, ...]

    def heads(self) -> dict[int, int]:
        """Each busy UAV's first target: the thesis's `pairs`."""
        return {uav: queue[0] for uav, queue in self.queues.items() if queue}

    def total(self) -> float:
        """The sum of every queued target's arrival time (min-sum's objective)."""
        return math.fsum(t for row in self.arrivals.values() for t in row)

    def makespan(self) -> float:
        """When the last queued target is reached (min-max's objective); 0 if none."""
        return max((row[-1] for row in self.arrivals.values() if row), default=0.0)


def check_input(times: Times, legs: Legs) -> int:
    """The number of targets; ValueError naming the first row of the wrong length."""
    count = leg_count(legs)
    for uav, row in times.items():
        if len(row) != count:
            raise ValueError(f"UAV {uav}: expected {count} approach times, got {len(row)}")
    if isinstance(legs, LegTables):
        return count
    for i, row in enumerate(legs):
        if len(row) != count:
            raise ValueError(f"legs from target {i}: expected {count}, got {len(row)}")
    return count


def arrivals_of(row: Sequence[float | None], legs: Rows, queue: Sequence[int]) -> list[float]:
    """The arrival time at each target of one UAV's queue (its approach times `row`)."""
    out: list[float] = []
    clock = 0.0
    previous: int | None = None
    for target in queue:
        if previous is None:
            first = row[target]
            assert first is not None
            clock = first
        else:
            clock += legs[previous][target]
        out.append(clock)
        previous = target
    return out


def finish(plan: Queues, times: Times, legs: Legs) -> QueuePlan:
    """The plan of these queues: arrivals computed, unassigned = the targets in none."""
    uavs = sorted(times)
    count = leg_count(legs)
    queued = {t for queue in plan.values() for t in queue}
    return QueuePlan(
        queues={uav: tuple(plan.get(uav, ())) for uav in uavs},
        arrivals={uav: tuple(queue_arrivals(times, legs, uav, plan.get(uav, ()))) for uav in uavs},
        unassigned=tuple(t for t in range(count) if t not in queued),
    )


def append_earliest(
    queues: Queues,
    clocks: dict[int, float],
    targets: Iterable[int],
    times: Times,
    legs: Legs,
) -> None:
    """Append each of `targets` to the queue where it is reached earliest, one at a time:
    the lowest (finishing time, Piccolo ID, target index) first. `clocks[uav]` is when
    the UAV finishes its queue (0 for an empty one: its approach time is then the
    arrival); both are updated in place. A target no UAV of `queues` can reach stays out.
    """
    left = sorted(set(targets))
    if not left:
        return  # every target placed already (the greedy's heads, N >= M): no UAV scanned
    uavs = sorted(queues)
    # Each UAV's best (finish, target) over the targets left: recomputed only for the UAV
    # that took a target and for those whose best was that target (50 x 200: one scan of
    # every pair, then ~U scans per step instead of U x T).
    best: dict[int, tuple[float, int] | None] = {}

    def best_of(uav: int) -> tuple[float, int] | None:
        row, queue, clock = times[uav], queues[uav], clocks[uav]
        found: tuple[float, int] | None = None
        if queue:
            legs_from = legs_of(legs, uav)[queue[-1]]
            for t in left:
                if usable(row[t]):
                    value = clock + legs_from[t]
                    # An infinite leg (no route around the no-fly zones) is never taken.
                    if value < math.inf and (found is None or value < found[0]):
                        found = (value, t)
        else:
            for t in left:
                time = row[t]
                if time is not None and math.isfinite(time) and (found is None or time < found[0]):
                    found = (time, t)
        return found

    for uav in uavs:
        best[uav] = best_of(uav)
    while left:
        choice: tuple[float, int, int] | None = None
        for uav in uavs:
            candidate = best[uav]
            if candidate is not None and (choice is None or candidate[0] < choice[0]):
                choice = (candidate[0], uav, candidate[1])
        if choice is None:
            return  # the rest is reachable by none of these UAVs
        value, uav, target = choice
        queues[uav].append(target)
        clocks[uav] = value
        left.remove(target)
        for other in uavs:
            candidate = best[other]
            if other == uav or (candidate is not None and candidate[1] == target):
                best[other] = best_of(other)


def greedy_queues(times: Times, legs: Legs, orders: Orders | None = None) -> Queues:
    """The thesis's one-each greedy, then the rest appended where reached earliest
    (`orders`: each UAV's `row_order`, where computed beforehand)."""
    count = leg_count(legs)
    heads = greedy_assign(times, count, orders).pairs
    queues: Queues = {uav: [heads[uav]] if uav in heads else [] for uav in sorted(times)}
    clocks = {uav: _head_time(times, uav, queues[uav]) for uav in queues}
    taken = set(heads.values())
    append_earliest(queues, clocks, (t for t in range(count) if t not in taken), times, legs)
    return queues


def _head_time(times: Times, uav: int, queue: list[int]) -> float:
    if not queue:
        return 0.0
    first = times[uav][queue[0]]
    assert first is not None
    return first


def plan_clocks(queues: Queues, times: Times, legs: Legs) -> dict[int, float]:
    """When each UAV finishes its queue (0 for an empty one)."""
    return {
        uav: (queue_arrivals(times, legs, uav, queue)[-1] if queue else 0.0)
        for uav, queue in queues.items()
    }
