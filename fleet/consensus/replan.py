"""Re-planning: the targets of UAVs that dropped out after the commitment go to the idle.

The consensus (`fleet.consensus.mission_round`) fixes one assignment, *epoch 0*. A UAV
that then drops out of the mission before reaching its target (its liveliness token
went away, it could not fly the target, its autopilot link was lost) leaves that target
orphaned. Every UAV still in the mission runs the same rule, with no coordinator:

* the **released** set is every team UAV known to have dropped out; it only grows, and
  UAVs merge the sets their teammates publish, so they converge on the same set;
* the assignment of epoch ``len(released)`` is a function of the epoch-0 assignment,
  the epoch-0 results and the released set alone: the targets of released holders are
  *orphaned*; the *candidates* are the UAVs of the epoch-0 team that are not released
  and had no target at epoch 0; the thesis greedy (`greedy_assign`) runs on the
  candidates' epoch-0 approach times to the orphaned targets only;
* its digest hashes the epoch-0 digest with the released set, so UAVs that re-planned
  on the same input publish the same digest and pairs, and the ground can check them.

Being a function of the set, not of the order in which losses were seen, two UAVs that
saw two losses in opposite orders still agree. The price: a UAV handed an orphaned target
at one epoch may be handed another orphan at a later one (never a UAV that held its
target at epoch 0). The approach times are those of the epoch-0 results, computed when
the mission started: re-planning needs no new round of results, so it is immediate, but
the times are older than the aircraft's position (see docs/lifecycle.md).

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from fleet.consensus.assignment import greedy_assign
from fleet.consensus.digest import sha256
from fleet.mission.messages import AssignmentReport

_REPLAN_VERSION = b"fleet.assignment.replan/v1\x00"


@dataclass(frozen=True)
class Replan:
    """The assignment of one epoch, derived from epoch 0 and a released set."""

    epoch: int
    released: tuple[int, ...]  #: ascending
    pairs: dict[int, int]  #: Piccolo ID -> target index, ascending by ID
    unassigned: tuple[int, ...]
    digest: str


def orphaned_targets(base: AssignmentReport, released: Iterable[int]) -> tuple[int, ...]:
    """Targets whose epoch-0 holder is released, ascending."""
    gone = set(released)
    return tuple(sorted(t for uav, t in base.pairs.items() if uav in gone))


def candidates(base: AssignmentReport, released: Iterable[int]) -> tuple[int, ...]:
    """UAVs of the epoch-0 team, not released, that had no target at epoch 0."""
    gone = set(released)
    holders = set(base.pairs)
    return tuple(sorted(u for u in base.team if u not in gone and u not in holders))


def replan_digest(base_digest: str, released: Iterable[int]) -> str:
    """16 hex digits identifying (epoch-0 results, released set); the base's at epoch 0."""
    gone = sorted(set(released))
    if not gone:
        return base_digest
    h = sha256(_REPLAN_VERSION)
    h.update(base_digest.encode("ascii", "replace"))
    for uav in gone:
        h.update(uav.to_bytes(2, "little"))
    return h.hexdigest()[:16]


def replan(
    base: AssignmentReport,
    times: Mapping[int, Sequence[float | None]],
    released: Iterable[int],
) -> Replan:
    """The assignment once `released` dropped out, from the epoch-0 `base` and `times`.

    `times[uav]` is a candidate's epoch-0 approach time to every target of the mission;
    raises KeyError naming a candidate whose times are missing (fetch them first).
    """
    gone = tuple(sorted(set(released) & set(base.team)))
    orphans = orphaned_targets(base, gone)
    pool = candidates(base, gone)
    kept = {uav: t for uav, t in base.pairs.items() if uav not in gone}
    if orphans and pool:
        # KeyError for a candidate whose times are missing: the caller fetches them.
        rows = {
            uav: [t if i in orphans else None for i, t in enumerate(times[uav])] for uav in pool
        }
        outcome = greedy_assign(rows, len(rows[pool[0]]))
        kept.update(outcome.pairs)
    taken = set(kept.values())
    return Replan(
        epoch=len(gone),
        released=gone,
        pairs={uav: kept[uav] for uav in sorted(kept)},
        unassigned=tuple(sorted(set(base.unassigned) | (set(orphans) - taken))),
        digest=replan_digest(base.digest, gone),
    )


def missing_times(
    base: AssignmentReport, times: Mapping[int, Sequence[float | None]], released: Iterable[int]
) -> tuple[int, ...]:
    """Candidates whose epoch-0 times this UAV lacks (a re-plan needs them when orphans exist)."""
    if not orphaned_targets(base, released):
        return ()
    return tuple(uav for uav in candidates(base, released) if uav not in times)
