"""Who is out of a mission after its commitment, as counts that only grow: a UAV that
comes back is in again.

Each team UAV has two counts: how many times it was counted out (`left`: its liveliness
stayed gone past the grace, it failed, its link was lost) and how many times it was
counted back (`back`: its liveliness came back while it was out). It is out while
`left > back`. A UAV that sees a teammate go sets its `left` to `back + 1`; one that sees
an out teammate come back sets its `back` to its `left`; and UAVs merge the counts their
teammates publish by taking the larger of each. Two UAVs that saw the same departure set
the same count, so merging them changes nothing; the merged counts of a team whose
reports all arrive are the same on every UAV whatever the order (a join-semilattice),
and the plan of an epoch is a function of them. The two sides of a partition, each of
which counted the other out, converge once they hear each other: every UAV of the other
side came back, and the counts say so on both.

A team UAV the epoch-0 plan was built without (a side's UAV that re-based onto the other
side's plan after a heal, fleet.consensus.heal) was out of that plan from its start: when
it is counted in (`join`) it is counted out once and back once, as if it had left and come
back, so the same rule merges it: every UAV that counts it in sets the same counts.

The epoch is the sum of all counts: it grows with every departure and every return, and
equals the number of UAVs out while nobody came back (`len(released)`, as before).

A third count per UAV, `asked`, is how many re-plans in changed air it asked for: a
UAV whose smoothed wind or airspeed moved away from the air its plan timed its legs in
(onboard.air_watch) adds one to its own. It is an epoch like a departure or a return:
the same team, solved again from every UAV's fresh standing (fleet.consensus.resolve),
so the plan in force is timed in the air of about the time its legs are flown.

Unlike a departure, which its teammates see for themselves (liveliness), an ask is known
only from the asking UAV's word, so only its word is believed: its teammates take it
from the standing it gives for that epoch or from any later report of its own (a
message's author is the UAV its key names, its signature checked under the secure
profile), never from a report that says another UAV asked (`own_asked`). Otherwise one
UAV, a captured identity say, could re-plan the team as often as it liked in another's
name. The rule keeps the merge a join-semilattice: what a report is believed for depends
on the report alone, each UAV's own count only grows, and every UAV that heard the
asker's latest word holds the same count.

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from fleet.consensus.digest import sha256

_MEMBERSHIP_VERSION = b"fleet.assignment.membership/v1\x00"
#: No re-plan in changed air asked for (a read-only empty mapping).
NONE_ASKED: Mapping[int, int] = MappingProxyType({})


@dataclass
class Membership:
    """One UAV's view of who is out of the mission (after the commitment)."""

    team: frozenset[int]
    left: dict[int, int] = field(default_factory=dict)
    back: dict[int, int] = field(default_factory=dict)
    #: Re-plans in changed air each UAV asked for (its own count, merged like the others).
    asked: dict[int, int] = field(default_factory=dict)

    def out(self) -> frozenset[int]:
        """The team UAVs out now."""
        return frozenset(u for u, n in self.left.items() if n > self.back.get(u, 0))

    def is_out(self, uav: int) -> bool:
        return self.left.get(uav, 0) > self.back.get(uav, 0)

    @property
    def epoch(self) -> int:
        return sum(self.left.values()) + sum(self.back.values()) + sum(self.asked.values())

    def ask(self, uav: int) -> bool:
        """Count one more re-plan in changed air asked for by team UAV `uav`; False if it
        is not one."""
        if uav not in self.team:
            return False
        self.asked[uav] = self.asked.get(uav, 0) + 1
        return True

    def leave(self, uavs: Iterable[int]) -> set[int]:
        """Count team UAVs out that are in; the ones that changed."""
        changed = set()
        for uav in uavs:
            if uav in self.team and not self.is_out(uav):
                self.left[uav] = self.back.get(uav, 0) + 1
                changed.add(uav)
        return changed

    def come_back(self, uavs: Iterable[int]) -> set[int]:
        """Count team UAVs that are out back in; the ones that changed."""
        changed = set()
        for uav in uavs:
            if uav in self.team and self.is_out(uav):
                self.back[uav] = self.left[uav]
                changed.add(uav)
        return changed

    def join(self, uavs: Iterable[int]) -> set[int]:
        """Count team UAVs in that were never counted (out of the plan since its start):
        out once and back once; the ones that changed."""
        changed = set()
        for uav in uavs:
            if uav in self.team and not self.left.get(uav) and not self.back.get(uav):
                self.left[uav] = self.back[uav] = 1
                changed.add(uav)
        return changed

    def merge(
        self,
        left: Mapping[int, int],
        back: Mapping[int, int],
        asked: Mapping[int, int] = NONE_ASKED,
    ) -> bool:
        """Take the larger of each count (team UAVs only); True if any changed."""
        changed = False
        for mine, theirs in ((self.left, left), (self.back, back), (self.asked, asked)):
            for uav, count in theirs.items():
                if uav in self.team and count > mine.get(uav, 0):
                    mine[uav] = count
                    changed = True
        return changed

    def covers(
        self,
        left: Mapping[int, int],
        back: Mapping[int, int],
        asked: Mapping[int, int] = NONE_ASKED,
    ) -> bool:
        """Merging these counts would change nothing."""
        return all(
            uav not in self.team or count <= mine.get(uav, 0)
            for mine, theirs in ((self.left, left), (self.back, back), (self.asked, asked))
            for uav, count in theirs.items()
        )


def own_asked(author: int, asked: Mapping[int, int]) -> dict[int, int]:
    """The `asked` counts a report written by team UAV `author` is believed for: its own
    ask count only (an ask is known from the asker's own word alone)."""
    count = asked.get(author, 0)
    return {author: count} if count > 0 else {}


def report_counts(
    released: Iterable[int], left: Mapping[int, int], back: Mapping[int, int]
) -> tuple[dict[int, int], dict[int, int]]:
    """A report's counts: a report without them (from a UAV that never saw anyone come
    back) counts each UAV it released out once."""
    counted = dict(left)
    for uav in released:
        counted.setdefault(uav, 1)
    return counted, dict(back)


def membership_digest(
    base_digest: str,
    left: Mapping[int, int],
    back: Mapping[int, int],
    asked: Mapping[int, int] = NONE_ASKED,
) -> str:
    """16 hex digits identifying (epoch-0 results, the counts) once somebody came back or
    asked for a re-plan in changed air (the `asked` counts hashed only when there are
    some: the digests of plans without them are the same bytes as before)."""
    h = sha256(_MEMBERSHIP_VERSION)
    h.update(base_digest.encode("ascii", "replace"))
    for counts in (left, back, asked) if asked else (left, back):
        for uav in sorted(counts):
            h.update(uav.to_bytes(2, "little"))
            h.update(counts[uav].to_bytes(4, "little"))
        h.update(b"\xff\xff")
    return h.hexdigest()[:16]
