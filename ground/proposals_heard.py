"""Every proposal heard for a mission, the ground's and each UAV's, and what became of it.

One code path for `send-targets --wait` and the page (`ground-cli gui`): for each
proposal heard (the ground's on `mission/{m}/proposal`, a UAV's on its own key
`mission/{m}/proposal/{id}`; in the secure profile the bus lets through only one its
author signed and the key entitles, as it does on board), the UAVs' own checks run on
the ground (`fleet.consensus.proposal_review`: the proposer's right, the plan's
validity, its score), and the verdict read from the UAVs' first plans (epoch 0,
revision 0: `fleet.consensus.proposal.adoption`). Only the UAVs' reported digests say a
proposal was adopted: a plan adopted from it has a digest of its own (its proposer and
queues hashed in), so a proposal the UAVs refused or never heard is never shown adopted.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

from fleet.consensus.proposal import Adoption, Verdict, adoption
from fleet.consensus.proposal_review import ProposalReview, Score, review_proposals
from fleet.mission.messages import (
    MISSION_MANAGER,
    AssignmentReport,
    MissionTargets,
    PlanProposal,
    UavResult,
)

__all__ = ["HeardProposal", "declined", "heard_proposals", "proposer_name", "team_plans"]


def proposer_name(proposer: int) -> str:
    return "the ground" if proposer == MISSION_MANAGER else f"UAV {proposer}"


def declined(targets: MissionTargets, results: Mapping[int, UavResult]) -> list[int]:
    """The named UAV proposers whose result said they will not propose (started without
    `--propose`, or without a solver): the team does not wait for them
    (fleet.consensus.proposal `awaited_proposers`)."""
    return [
        uav
        for uav in targets.proposers
        if uav != MISSION_MANAGER and uav in results and results[uav].proposes is False
    ]


def _ids(uavs: Iterable[int]) -> str:
    return ", ".join(map(str, uavs))


@dataclass(frozen=True)
class HeardProposal:
    """A proposal heard: what the UAVs' checks say of it, and what their decisions did."""

    proposal: PlanProposal
    review: ProposalReview
    adoption: Adoption
    #: The other proposals heard that UAVs which did not adopt this one adopted:
    #: (proposer, the UAVs), by proposer.
    instead: tuple[tuple[int, tuple[int, ...]], ...] = ()

    @property
    def proposer(self) -> int:
        return self.proposal.proposer

    def summary(self) -> str:
        """One line: the verdict (the UAVs' digests), then the ground's check of it."""
        said = self.adoption.summary()
        if self.instead:
            said += (
                " ("
                + "; ".join(
                    f"{proposer_name(p)}'s adopted by {_ids(uavs)}" for p, uavs in self.instead
                )
                + ")"
            )
        return f"{said}; {self.review.summary()}"

    def to_json(self) -> dict[str, object]:
        return {
            "proposer": self.proposer,
            "by": proposer_name(self.proposer),
            **self.adoption.to_json(),
            **self.review.to_json(),
            "instead": [{"proposer": p, "adopted_by": list(uavs)} for p, uavs in self.instead],
            "summary": self.summary(),
        }


def heard_proposals(
    targets: MissionTargets,
    results: Mapping[int, UavResult],
    proposals: Mapping[int, PlanProposal],
    decisions: Collection[AssignmentReport],
) -> list[HeardProposal]:
    """Each of `proposals` (by proposer, for `targets`' mission as first sent) checked
    against the team's `results`, and what the UAVs' first plans among `decisions`
    (their reported digests) say of it; in increasing proposer ID."""
    reviews = review_proposals(targets, results, proposals.values())
    adoptions = {p: adoption(proposal, decisions) for p, proposal in sorted(proposals.items())}
    heard = []
    for proposer, seen in adoptions.items():
        instead = tuple(
            (other, took)
            for other, theirs in adoptions.items()
            if other != proposer and seen.verdict is not Verdict.ADOPTED
            if (took := tuple(u for u in theirs.adopted_by if u in seen.other_by))
        )
        heard.append(HeardProposal(proposals[proposer], reviews[proposer], seen, instead))
    return heard


def team_plans(decisions: Iterable[AssignmentReport], mission: int) -> list[dict[str, object]]:
    """The plans the UAVs' first decisions of `mission` committed to, one per digest:
    who reported it and its score (from the arrivals they reported)."""
    by: dict[str, list[AssignmentReport]] = {}
    for report in sorted(decisions, key=lambda r: r.uav):
        if report.mission == mission and not (report.epoch or report.revision):
            by.setdefault(report.digest, []).append(report)
    return [
        {
            "digest": digest,
            "by": [r.uav for r in reports],
            "score": Score.of_report(reports[0]).to_json(),
        }
        for digest, reports in by.items()
    ]
