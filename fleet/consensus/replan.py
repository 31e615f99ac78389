"""Re-planning: the queues of UAVs that dropped out go to the survivors' queues.

The consensus (`fleet.consensus.mission_round`) fixes one plan, *epoch 0*: every UAV's
ordered queue of targets (`fleet.consensus.queues`). A UAV that then drops out of the
mission (its liveliness token went away, it could not fly its target, its autopilot
link was lost) leaves its queue orphaned: the target it was flying and every one after
it. Every UAV still in the mission runs the same rule, with no coordinator:

* the **released** set is every team UAV out of the mission now, kept as counts that
  only grow (`fleet.consensus.membership`: a UAV that comes back is in again), which
  UAVs merge from their teammates' reports, so they converge on the same set;
* the plan of epoch ``len(released)`` is a function of the epoch-0 plan, the epoch-0
  results and the released set alone: the queues of released UAVs are *orphaned*; every
  survivor keeps its own epoch-0 queue, and the orphans are appended, one at a time, to
  the survivor's queue where each is reached earliest (`append_earliest`: the lowest
  (finishing time, Piccolo ID, target index)), whether that survivor had targets at
  epoch 0 or none; a target no survivor has an approach time to is `unserved`, with the
  reason;
* a survivor that is **finished** (it reached targets itself and nothing of its queue is
  left) takes an orphan only when no other survivor has an approach time to it: its
  epoch-0 times are from where it was at the start, and it has flown on since its queue
  ended, so the append rule's arrival for it is the least true of all; it takes part
  again with fresh times (`fleet.consensus.resolve`), and a target is never dropped while
  a finished UAV can reach it (the last resort);
* its digest hashes the epoch-0 digest with the released set (and the finished
  survivors, when there are orphans to hand out), so UAVs that re-planned on the same
  input publish the same digest and queues, and the ground can check them.

Being a function of the set, not of the order in which losses were seen, two UAVs that
saw two losses in opposite orders still agree. Orphans go to the ends of queues, never
in front of a survivor's own targets: what a survivor flies now does not change, and a
target a released UAV had already reached is skipped by its new holder when it comes to
it (it heard that outcome). The times are those of the epoch-0 results, computed when the
mission started: this plan needs no new round of results, but the times are older than
the aircraft's position. It is each epoch's fallback: the plan committed is solved again
from the survivors' fresh times when they all come in time (`fleet.consensus.resolve`,
docs/lifecycle.md).

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from fleet.consensus.digest import sha256
from fleet.consensus.queues import Legs, QueuePlan, Queues, append_earliest, finish, plan_clocks
from fleet.mission.messages import AssignmentReport

_REPLAN_VERSION = b"fleet.assignment.replan/v1\x00"
_FINISHED_VERSION = b"fleet.assignment.finished/v1\x00"
#: Why an orphan is in no queue after a re-plan.
NO_SURVIVOR = "no surviving UAV has an approach time to it"


@dataclass(frozen=True)
class Replan:
    """The plan of one epoch, derived from epoch 0 and a released set."""

    epoch: int
    released: tuple[int, ...]  #: ascending
    plan: QueuePlan  #: the survivors' queues (released UAVs: none)
    unserved: dict[int, str]  #: target -> why no survivor serves it
    digest: str
    #: The finished survivors, handed an orphan only as the last resort (ascending;
    #: empty when no orphan was handed out: then they change nothing).
    finished: tuple[int, ...] = ()

    @property
    def pairs(self) -> dict[int, int]:
        """Each busy survivor's first target, ascending by ID."""
        return self.plan.heads()

    @property
    def unassigned(self) -> tuple[int, ...]:
        return tuple(sorted(self.unserved))


def base_queues(base: AssignmentReport) -> dict[int, tuple[int, ...]]:
    """Epoch 0's queue of every team UAV (from `pairs` for a report without queues)."""
    if base.queues:
        return {uav: base.queues.get(uav, ()) for uav in base.team}
    return {uav: (base.pairs[uav],) if uav in base.pairs else () for uav in base.team}


def orphaned_targets(base: AssignmentReport, released: Iterable[int]) -> tuple[int, ...]:
    """Targets queued at epoch 0 by a released UAV, ascending."""
    gone = set(released)
    return tuple(sorted(t for uav, q in base_queues(base).items() if uav in gone for t in q))


def candidates(base: AssignmentReport, released: Iterable[int]) -> tuple[int, ...]:
    """UAVs of the epoch-0 team, not released: every one may take orphans."""
    gone = set(released)
    return tuple(sorted(u for u in base.team if u not in gone))


def replan_digest(base_digest: str, released: Iterable[int]) -> str:
    """16 hex digits identifying (epoch-0 results, released set); the base's at epoch 0."""
    return _with_uavs(_REPLAN_VERSION, base_digest, released)


def finished_digest(digest: str, finished: Iterable[int]) -> str:
    """`digest` with the finished survivors an epoch's orphans avoided; `digest` itself
    when there are none (the plan does not depend on them)."""
    return _with_uavs(_FINISHED_VERSION, digest, finished)


def _with_uavs(version: bytes, digest: str, uavs: Iterable[int]) -> str:
    """`digest` extended by a set of UAVs under `version`; `digest` itself when empty."""
    ids = sorted(set(uavs))
    if not ids:
        return digest
    h = sha256(version)
    h.update(digest.encode("ascii", "replace"))
    for uav in ids:
        h.update(uav.to_bytes(2, "little"))
    return h.hexdigest()[:16]


def replan(
    base: AssignmentReport,
    times: Mapping[int, Sequence[float | None]],
    released: Iterable[int],
    legs: Legs,
    *,
    removed: Iterable[int] = (),
    added: Iterable[int] = (),
    finished: Iterable[int] = (),
) -> Replan:
    """The plan once `released` dropped out, from the epoch-0 `base`, `times` and `legs`;
    with the mission changed in flight (fleet.consensus.mission_change), `removed`
    targets leave every queue and the `added` ones are handed out like orphans. The
    `finished` survivors take only the orphans no other survivor can reach.

    `times[uav]` is a survivor's epoch-0 approach time to every target of the mission
    (and its estimate to each added one); raises KeyError naming a survivor whose times
    are missing (fetch them first).
    """
    gone = tuple(sorted(set(released) & set(base.team)))
    off = set(removed)
    orphans = tuple(
        sorted({t for t in orphaned_targets(base, gone) if t not in off} | (set(added) - off))
    )
    pool = candidates(base, gone)
    queues: Queues = {
        uav: [t for t in q if t not in off] for uav, q in base_queues(base).items() if uav in pool
    }
    done = tuple(sorted(set(finished) & set(pool))) if orphans else ()
    if orphans or off:
        # KeyError for a survivor whose times are missing: the caller fetches them.
        rows = {uav: times[uav] for uav in pool}
        clocks = plan_clocks(queues, rows, legs)
        # The survivors still at work first; the finished ones, the last resort, take
        # what none of them can reach (the same lists: appended in place).
        for group in ([u for u in pool if u not in done], list(done)):
            placed = {t for q in queues.values() for t in q}
            left = [t for t in orphans if t not in placed]
            sub = {uav: queues[uav] for uav in group}
            append_earliest(sub, {uav: clocks[uav] for uav in group}, left, rows, legs)
        plan = finish(queues, rows, legs)
    else:  # nothing moves: the survivors' epoch-0 queues and arrivals
        plan = QueuePlan(
            queues={uav: tuple(q) for uav, q in queues.items()},
            arrivals={uav: base.arrivals.get(uav, ()) for uav in queues},
            unassigned=base.unassigned,
        )
    unserved = {
        t: base.unserved.get(t, "no UAV had an approach time to it")
        for t in base.unassigned
        if t not in off
    }
    queued = {t for q in queues.values() for t in q}
    unserved.update({t: NO_SURVIVOR for t in orphans if t not in queued})
    return Replan(
        epoch=len(gone),
        released=gone,
        plan=plan,
        unserved=dict(sorted(unserved.items())),
        digest=finished_digest(replan_digest(base.digest, gone), done),
        finished=done,
    )


def missing_times(
    base: AssignmentReport, times: Mapping[int, Sequence[float | None]], released: Iterable[int]
) -> tuple[int, ...]:
    """Survivors whose epoch-0 times this UAV lacks (a re-plan needs them when orphans
    exist)."""
    if not orphaned_targets(base, released):
        return ()
    return tuple(uav for uav in candidates(base, released) if uav not in times)
