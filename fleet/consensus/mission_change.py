"""A mission changed in flight: targets added, targets removed.

The ground puts the whole mission again, one revision higher (`MissionTargets.revision`):
the targets added go after the others, so an index never changes, and `removed` holds
every target taken off so far. Every UAV that committed to the mission takes a later
revision that extends the one it holds (`change_problem`) and re-plans at once, a new
epoch of the same mission: a removed target leaves every queue and is never flown; an
added one is handed out like an orphan, to the queue where it is reached earliest
(`fleet.consensus.replan`). Nothing new is measured for it: a UAV's approach time to an
added target is estimated from its epoch-0 result, in a straight line from where it
planned at the airspeed it planned with (`estimated_times`), the same on every UAV, so
the plan of a revision stays a function of what every UAV holds.

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable

import msgspec

from fleet.consensus.digest import sha256
from fleet.consensus.legs import LEG_SPEED_MPS
from fleet.geo.mercator import distance_m
from fleet.mission.messages import MissionTargets, Target, UavResult

_CHANGE_VERSION = b"fleet.assignment.change/v1\x00"


def planned_count(targets: MissionTargets) -> int:
    """How many of the mission's targets its first revision had (the results time them)."""
    return len(targets.targets) if targets.planned is None else targets.planned


def added_targets(targets: MissionTargets) -> tuple[int, ...]:
    """The indexes of the targets added in flight, still wanted."""
    removed = set(targets.removed)
    count = planned_count(targets)
    return tuple(i for i in range(count, len(targets.targets)) if i not in removed)


def first_revision(targets: MissionTargets) -> MissionTargets:
    """The mission as first sent (what the UAVs' results time), from any revision."""
    if targets.revision == 0:
        return targets
    return msgspec.structs.replace(
        targets,
        targets=targets.targets[: planned_count(targets)],
        revision=0,
        removed=(),
        planned=None,
    )


def change_problem(held: MissionTargets, new: MissionTargets) -> str | None:
    """Why `new` is not a later revision of the mission `held`; None if it is."""
    if new.mission != held.mission:
        return f"mission {new.mission} is not mission {held.mission}"
    if new.revision <= held.revision:
        return f"revision {new.revision} is not later than revision {held.revision}"
    if (new.team, new.zones, new.objective) != (held.team, held.zones, held.objective):
        return "its team, no-fly zones or objective differ"
    if planned_count(new) != planned_count(held):
        return "its first revision's target count differs"
    if new.targets[: len(held.targets)] != held.targets:
        return "it changes targets it had already (indexes never change; add, or remove)"
    if not set(held.removed) <= set(new.removed):
        return "it puts back a removed target"
    beyond = [i for i in new.removed if i >= len(new.targets)]
    if beyond:
        return f"it removes target {beyond[0]}, beyond its {len(new.targets)} targets"
    return None


def next_revision(
    held: MissionTargets, added: Iterable[Target] = (), removed: Iterable[int] = ()
) -> MissionTargets:
    """The mission `held` with `added` after its targets and `removed` taken off: one
    revision higher. Raises ValueError naming an index that is not one of its targets,
    or removed already."""
    new_targets = held.targets + tuple(added)
    gone = set(held.removed)
    for index in removed:
        if not 0 <= index < len(held.targets):
            raise ValueError(f"target {index} is not one of the mission's {len(held.targets)}")
        if index in gone:
            raise ValueError(f"target {index} was removed already")
        gone.add(index)
    return msgspec.structs.replace(
        held,
        targets=new_targets,
        revision=held.revision + 1,
        removed=tuple(sorted(gone)),
        planned=planned_count(held),
    )


def estimated_times(
    result: UavResult, targets: tuple[Target, ...], indexes: Iterable[int]
) -> tuple[float | None, ...]:
    """`result`'s UAV's approach time to each of `indexes` (targets added after its
    result): straight from where it planned, at the airspeed it planned with; None where
    its result does not say where it was."""
    if result.lat is None or result.lon is None:
        return tuple(None for _ in indexes)
    speed = result.airspeed or LEG_SPEED_MPS
    start = (result.lat, result.lon)
    return tuple(distance_m(start, (targets[i].lat, targets[i].lon)) / speed for i in indexes)


def change_digest(digest: str, targets: MissionTargets) -> str:
    """16 hex digits identifying (a plan's digest, the mission's revision); the digest
    itself at revision 0."""
    if targets.revision == 0:
        return digest
    h = sha256(_CHANGE_VERSION)
    h.update(digest.encode("ascii", "replace"))
    h.update(targets.revision.to_bytes(2, "little"))
    h.update(len(targets.targets).to_bytes(2, "little"))
    for index in targets.removed:
        h.update(index.to_bytes(2, "little"))
    return h.hexdigest()[:16]
