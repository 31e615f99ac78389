"""Solving what is left: an epoch's plan from the taking-part UAVs' fresh standings.

`fleet.consensus.replan` derives every epoch from the epoch-0 plan and its times: the
orphans go to the ends of the survivors' queues, timed from where the aircraft were when
the mission started. This module is the other way, a new round over what is left: each
UAV taking part in the epoch says where it stands now (`Standing`: its approach time from
where it is now to every target of the mission, the target it is flying, the targets it
reached itself), and the remaining targets (every target not removed and not reached by
a taking-part UAV's own word) are solved again under the mission's objective
(`resolve`), from those times. Every UAV that holds the same standings computes the same
plan, whose digest (`resolve_digest`) hashes the epoch's basis (the fallback plan's
digest) with every standing, so UAVs and the ground can check it.

A UAV keeps its current target first unless the objective gains by changing it: the plan
with every current target kept first (`pinned`) is solved, and the plan solved from
scratch (`free`) replaces it only when it serves more targets, or the same number with
the objective's measure lower by more than `GAIN` (relative): the total of arrivals for
min-sum and for the greedy (which has no measure of its own), the last arrival for
min-max.

`solve_epoch` is the epoch's decision: the resolved plan when every survivor of the
fallback plan gave a standing, else the fallback itself (the append rule of
`fleet.consensus.replan`, a function of what every UAV holds from epoch 0): nothing is
dropped for a missing standing. A survivor that gave a standing takes part whatever it
did before, so a UAV that had finished its queue holds only what its fresh times win.

Pure: no I/O.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

from fleet.consensus.assignment import row_bytes, usable
from fleet.consensus.digest import sha256
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import (
    Legs,
    LegTables,
    Matrix,
    QueuePlan,
    Rows,
    finish,
    leg_count,
    legs_of,
    reference_legs,
)
from fleet.consensus.replan import Replan
from fleet.mission.objective import Objective

_RESOLVE_VERSION = b"fleet.assignment.resolve/v1\x00"
_INDEX = struct.Struct("<H")
_NONE = 0xFFFF
#: The free plan must be better than the pinned one by more than this (relative).
GAIN = 1e-6
#: Why a remaining target is in no queue of a resolved plan.
NO_TAKER = "no UAV taking part has an approach time to it"


@dataclass(frozen=True, slots=True)
class Standing:
    """One taking-part UAV's word for an epoch: where it stands now."""

    #: Its approach time (s) from where it is now to every target of the mission (the
    #: current revision's), None where it has no answer.
    times: tuple[float | None, ...]
    #: The target it is flying now (kept first unless the objective gains), None if none.
    flying: int | None = None
    #: The targets it reached itself: none of them is planned again. (A UAV's word is
    #: believed of itself only: a target another UAV reached is planned again, and
    #: skipped by its holder on that UAV's own word.)
    reached: frozenset[int] = field(default_factory=frozenset)


@dataclass(frozen=True, slots=True)
class Resolved:
    """The plan of what is left, over the mission's target indexes."""

    plan: QueuePlan  #: every taking-part UAV's queue (ascending ID); arrivals from now
    kept: bool  #: every UAV kept its current target first (the pinned plan won)
    unserved: dict[int, str]  #: remaining target -> why nobody serves it


def remaining_targets(
    count: int, removed: Iterable[int], standings: Mapping[int, Standing]
) -> tuple[int, ...]:
    """The targets left to plan: not removed, not reached by a standing's own word."""
    gone = set(removed)
    for standing in standings.values():
        gone |= standing.reached
    return tuple(t for t in range(count) if t not in gone)


class _Subset(LegTables):
    """The legs between `index` (the remaining targets), renumbered 0.. in that order."""

    def __init__(self, legs: Legs, index: Sequence[int]) -> None:
        self._legs = legs
        self._index = tuple(index)
        self._rows: dict[int, _SubRows] = {}
        self._reference: list[list[float]] | None = None

    @property
    def count(self) -> int:
        return len(self._index)

    def of(self, uav: int) -> Rows:
        rows = self._rows.get(uav)
        if rows is None:
            rows = self._rows[uav] = _SubRows(legs_of(self._legs, uav), self._index)
        return rows

    def reference(self) -> Matrix:
        if self._reference is None:
            full = reference_legs(self._legs)
            self._reference = [[full[i][j] for j in self._index] for i in self._index]
        return self._reference

    def arrivals(self, uav: int, first: float, queue: Sequence[int]) -> list[float]:
        full = [self._index[t] for t in queue]
        if isinstance(self._legs, LegTables):
            return self._legs.arrivals(uav, first, full)
        out = [first]
        for i, j in itertools.pairwise(full):
            out.append(out[-1] + self._legs[i][j])
        return out


class _SubRows:
    """One UAV's legs between the remaining targets, each row made when first asked."""

    def __init__(self, full: Rows, index: tuple[int, ...]) -> None:
        self._full = full
        self._index = index
        self._made: dict[int, list[float]] = {}

    def __getitem__(self, i: int, /) -> Sequence[float]:
        row = self._made.get(i)
        if row is None:
            source = self._full[self._index[i]]
            row = self._made[i] = [source[j] for j in self._index]
        return row


def _key(plan: QueuePlan, objective: Objective) -> tuple[int, float, float]:
    """What the objective compares: fewer targets left out first, then its measure."""
    if objective is Objective.MIN_MAX:
        return len(plan.unassigned), plan.makespan(), plan.total()
    return len(plan.unassigned), plan.total(), plan.makespan()


def _gains(free: tuple[int, float, float], pinned: tuple[int, float, float]) -> bool:
    if free[0] != pinned[0]:
        return free[0] < pinned[0]
    return free[1] < pinned[1] - GAIN * abs(pinned[1])


def _pins(
    rows: Mapping[int, Sequence[float | None]], flying: Mapping[int, int | None]
) -> dict[int, int]:
    """Each UAV's current target (a subset index) it keeps first; a target two UAVs fly
    (a partition) is kept by the one with the lower time to it, then the lower ID."""
    claims: dict[int, tuple[float, int]] = {}
    for uav in sorted(rows):
        target = flying.get(uav)
        if target is None or not usable(rows[uav][target]):
            continue
        time = rows[uav][target]
        assert time is not None
        held = claims.get(target)
        if held is None or (time, uav) < held:
            claims[target] = (time, uav)
    return {uav: target for target, (_, uav) in claims.items()}


def _pinned_plan(
    rows: Mapping[int, Sequence[float | None]],
    legs: _Subset,
    pins: Mapping[int, int],
    objective: Objective,
) -> dict[int, list[int]]:
    """Every pinned UAV's current target first, the other targets solved after it: a
    pinned UAV's time to a target is its time to its current one plus the leg on."""
    taken = set(pins.values())
    rest = [t for t in range(legs.count) if t not in taken]
    if not rest:
        return {uav: [pins[uav]] if uav in pins else [] for uav in sorted(rows)}
    shifted: dict[int, tuple[float | None, ...]] = {}
    for uav in sorted(rows):
        if uav in pins:
            head = pins[uav]
            start = rows[uav][head]
            assert start is not None
            table = legs.of(uav)[head]
            shifted[uav] = tuple(
                start + table[t] if usable(rows[uav][t]) and math.isfinite(table[t]) else None
                for t in rest
            )
        else:
            shifted[uav] = tuple(rows[uav][t] for t in rest)
    solved = plan_queues(shifted, _Subset(legs, rest), objective)
    return {
        uav: ([pins[uav]] if uav in pins else []) + [rest[t] for t in solved.queues[uav]]
        for uav in sorted(rows)
    }


def resolve(
    standings: Mapping[int, Standing],
    remaining: Iterable[int],
    legs: Legs,
    objective: Objective,
) -> Resolved:
    """The plan of the `remaining` targets among the UAVs of `standings`, from their
    fresh times, under `objective` (the module docstring). `legs` are between every
    target of the mission; ValueError if a standing's times are not one per target."""
    count = leg_count(legs)
    for uav, standing in standings.items():
        if len(standing.times) != count:
            raise ValueError(
                f"UAV {uav}: expected {count} approach times, got {len(standing.times)}"
            )
    index = tuple(sorted(set(remaining)))
    sub = _Subset(legs, index)
    rows = {uav: tuple(standings[uav].times[t] for t in index) for uav in sorted(standings)}
    position = {t: i for i, t in enumerate(index)}
    flying = {
        uav: position.get(s.flying) if s.flying is not None else None
        for uav, s in standings.items()
    }
    pinned = finish(_pinned_plan(rows, sub, _pins(rows, flying), objective), rows, sub)
    kept = True
    chosen = pinned
    if any(v is not None for v in flying.values()):
        free = plan_queues(rows, sub, objective)
        if _gains(_key(free, objective), _key(pinned, objective)):
            chosen, kept = free, False
    plan = QueuePlan(
        queues={uav: tuple(index[t] for t in q) for uav, q in chosen.queues.items()},
        arrivals=dict(chosen.arrivals),
        unassigned=tuple(index[t] for t in chosen.unassigned),
    )
    return Resolved(plan, kept, {t: NO_TAKER for t in plan.unassigned})


def resolve_digest(
    basis: str,
    standings: Mapping[int, Standing],
    remaining: Iterable[int],
    objective: Objective,
) -> str:
    """16 hex digits identifying (the epoch's basis, every standing, the remaining
    targets, the objective): UAVs that resolved the same input publish the same one."""
    h = sha256(_RESOLVE_VERSION)
    h.update(basis.encode("ascii", "replace") + b"\x00")
    h.update(objective.value.encode("ascii") + b"\x00")
    for uav in sorted(standings):
        standing = standings[uav]
        h.update(row_bytes(uav, standing.times))
        h.update(_INDEX.pack(_NONE if standing.flying is None else standing.flying))
        h.update(b"".join(_INDEX.pack(t) for t in sorted(standing.reached)) + b"\xff\xff")
    h.update(b"".join(_INDEX.pack(t) for t in sorted(set(remaining))))
    return h.hexdigest()[:16]


def solve_epoch(
    fallback: Replan,
    standings: Mapping[int, Standing],
    legs: Legs,
    objective: Objective,
    removed: Iterable[int] = (),
) -> tuple[Replan, bool]:
    """The epoch's plan, and whether it was resolved from fresh standings: resolved when
    every survivor of `fallback` (the epoch's append plan, `fleet.consensus.replan`)
    gave a standing, else `fallback` itself. Standings of UAVs that are not survivors
    are ignored. `legs` are between every target of the mission (its current revision)."""
    survivors = tuple(sorted(fallback.plan.queues))
    if not survivors or any(uav not in standings for uav in survivors):
        return fallback, False
    taking_part = {uav: standings[uav] for uav in survivors}
    left = remaining_targets(leg_count(legs), removed, taking_part)
    solved = resolve(taking_part, left, legs, objective)
    digest = resolve_digest(fallback.digest, taking_part, left, objective)
    return replace(fallback, plan=solved.plan, unserved=solved.unserved, digest=digest), True
