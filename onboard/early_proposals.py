"""Plans proposed for a mission this UAV does not hold yet, kept for when it arrives.

A proposal and its mission travel on different keys, and may come in either order: a
teammate's proposal overtakes the mission on another path (the mission reaches this UAV
by a catch-up, after a freeze or through a router mesh), or a UAV learns its mission
late. Dropped, such a proposal would leave this UAV waiting in vain for a proposer its
teammates heard, then deciding without the plan they adopted: two plans. So a proposal
for a later mission than the one held is kept, and handed over when that mission
starts, where it is checked like one heard after it (the proposer's right under the
mission as it arrives, the plan itself at the decision: onboard.mission_participation).

Bounded, whatever the proposers send: the latest of each proposer for each mission, at
most PER_PROPOSER missions of each proposer (its newest: a hostile proposer flooding
mission ids pushes out its own, never another's) and MAX_KEPT in all (the first kept
goes first). What is not kept is returned, to be counted: pushed out, or for a mission
older than the one that starts (never to be held). Pure: no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fleet.mission.messages import PlanProposal

#: Missions kept per proposer (the newest ids): the ground's next, or a teammate's.
PER_PROPOSER = 2
#: Proposals kept in all (each one plan: at most a mission's queues).
MAX_KEPT = 16


@dataclass
class EarlyProposals:
    """Proposals for missions not held yet, by (mission, proposer): the latest of each."""

    per_proposer: int = PER_PROPOSER
    max_kept: int = MAX_KEPT
    _kept: dict[tuple[int, int], PlanProposal] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self._kept)

    def keep(self, proposal: PlanProposal) -> list[PlanProposal]:
        """Keep `proposal` (in place of its proposer's earlier one for that mission, as a
        round keeps a proposer's latest); the proposals pushed out by it (itself, if its
        proposer holds newer missions), to be counted."""
        slot = (proposal.mission, proposal.proposer)
        dropped: list[PlanProposal] = []
        self._kept.pop(slot, None)
        self._kept[slot] = proposal
        own = sorted(m for m, p in self._kept if p == proposal.proposer)
        for mission in own[: max(0, len(own) - self.per_proposer)]:
            dropped.append(self._kept.pop((mission, proposal.proposer)))
        while len(self._kept) > self.max_kept:
            dropped.append(self._kept.pop(next(iter(self._kept))))
        return dropped

    def take(self, mission: int) -> tuple[list[PlanProposal], list[PlanProposal]]:
        """As `mission` starts: its proposals, in the order they came, and those of older
        missions, which it supersedes (never to be held: to be counted). Later missions'
        stay kept."""
        taken = [p for (m, _), p in self._kept.items() if m == mission]
        stale = [p for (m, _), p in self._kept.items() if m < mission]
        self._kept = {slot: p for slot, p in self._kept.items() if slot[0] > mission}
        return taken, stale
