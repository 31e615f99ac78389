"""Proposed plans verified: every UAV re-scores a proposal with the deterministic
scorer, refuses an invalid one whole, adopts the best by (score, proposer), and every
UAV holding the same results and proposals reports the same plan and digest."""

from __future__ import annotations

import msgspec
import pytest

from fleet.consensus.mission_round import MissionRound
from fleet.consensus.proposal import Verdict, adoption, plan_key
from fleet.consensus.queues import finish
from fleet.mission.messages import MISSION_MANAGER, PlanProposal
from fleet.mission.objective import Objective
from tests.support.proposal_instance import BETTER, mission_and_results


def _round(own: int, proposals_s: float = 0.0) -> MissionRound:
    mission, results = mission_and_results(proposals_s)
    mission_round = MissionRound(targets=mission, own_id=own, started=0.0)
    for result in results if own == 3 else reversed(results):
        assert mission_round.add_result(result)
    return mission_round


def _inputs(mission_round: MissionRound) -> str:
    used = {uav: r.times for uav, r in mission_round.results.items()}
    return mission_round.results_digest(used)


def _proposal(mission_round: MissionRound, **changes: object) -> PlanProposal:
    proposal = PlanProposal(
        mission=9,
        proposer=MISSION_MANAGER,
        digest=_inputs(mission_round),
        objective=Objective.MIN_SUM,
        queues=BETTER,
    )
    return msgspec.structs.replace(proposal, **changes)


def test_a_better_proposal_is_adopted_by_every_uav_with_one_digest() -> None:
    baseline = _round(3).decide({3, 5})
    reports = []
    for own in (3, 5):
        mission_round = _round(own)
        assert mission_round.add_proposal(_proposal(mission_round))
        reports.append(mission_round.decide({3, 5}))
    first, second = reports
    assert first.queues == second.queues == BETTER
    assert first.digest == second.digest != baseline.digest
    assert first.arrivals == second.arrivals
    # The scorer says it is better: the sum of arrivals is lower than the baseline's.
    assert sum(sum(a) for a in first.arrivals.values()) < sum(
        sum(a) for a in baseline.arrivals.values()
    )


@pytest.mark.parametrize(
    ("changes", "why"),
    [
        ({"queues": {3: (4, 0, 2), 5: (2, 1, 5, 3)}}, "target 2 twice"),
        ({"queues": {3: (4, 0), 5: (2, 1, 5)}}, "target 3 in no queue"),
        ({"queues": {3: (4, 0), 5: (2, 1, 5), 7: (3,)}}, "UAV 7, which takes no part"),
        ({"queues": {3: (4, 0), 5: (2, 1, 5, 9)}}, "target 9 of 6"),
        ({"digest": "0123456789abcdef"}, "other results"),
        ({"objective": Objective.MIN_MAX}, "for min-max"),
    ],
)
def test_an_invalid_proposal_changes_nothing(changes: dict[str, object], why: str) -> None:
    baseline = _round(3).decide({3, 5})
    mission_round = _round(3)
    assert mission_round.add_proposal(_proposal(mission_round, **changes))
    report = mission_round.decide({3, 5})
    assert (report.queues, report.digest) == (baseline.queues, baseline.digest)
    assert why in mission_round.refused_proposals[MISSION_MANAGER]


def test_a_worse_proposal_is_not_adopted_and_a_late_one_is_refused() -> None:
    baseline = _round(3).decide({3, 5})
    mission_round = _round(3)
    worse = {3: (0, 1, 2, 3, 4, 5), 5: ()}
    assert mission_round.add_proposal(_proposal(mission_round, queues=worse))
    report = mission_round.decide({3, 5})
    assert (report.queues, report.digest) == (baseline.queues, baseline.digest)
    assert not mission_round.add_proposal(_proposal(mission_round))  # after the commitment


def test_the_decision_waits_for_a_proposal_within_its_window_only() -> None:
    mission_round = _round(3, proposals_s=5.0)
    assert not mission_round.ready(1.0, {3, 5})  # every result held, no proposal yet
    assert mission_round.ready(5.0, {3, 5})  # the window closed: the baseline
    waiting = _round(3, proposals_s=5.0)
    waiting.add_proposal(_proposal(waiting))
    assert waiting.ready(1.0, {3, 5})


def test_the_proposal_here_is_better_by_the_scorer() -> None:
    """The premise of the tests above."""
    mission_round = _round(3)
    used = {uav: r.times for uav, r in mission_round.results.items()}
    legs = mission_round.air_legs(used)
    baseline = mission_round.decide({3, 5})
    better = finish({u: list(q) for u, q in BETTER.items()}, used, legs)
    mine = finish({u: list(q) for u, q in baseline.queues.items()}, used, legs)
    assert plan_key(better, Objective.MIN_SUM) < plan_key(mine, Objective.MIN_SUM)


def test_an_invalid_proposal_does_not_close_the_window() -> None:
    mission_round = _round(3, proposals_s=5.0)
    mission_round.add_proposal(_proposal(mission_round, proposer=1, queues={3: (0, 0)}))
    assert not mission_round.ready(1.0, {3, 5})
    mission_round.add_proposal(_proposal(mission_round))
    assert mission_round.ready(1.0, {3, 5})


def test_adoption_is_read_from_the_digests_the_uavs_decided_on() -> None:
    """The ground tells from each UAV's reported digest alone whether it adopted the
    proposal, kept the baseline, or decided on other results."""
    with_it = _round(3)
    proposal = _proposal(with_it)
    assert with_it.add_proposal(proposal)
    adopted = with_it.decide({3, 5})
    kept = _round(5).decide({3, 5})  # never heard it
    assert adoption(proposal, []).verdict is Verdict.WAITING
    seen = adoption(proposal, [adopted])
    assert (seen.verdict, seen.adopted_by, seen.adopted_digest) == (
        Verdict.ADOPTED,
        (3,),
        adopted.digest,
    )
    seen = adoption(proposal, [kept])
    assert (seen.verdict, seen.baseline_by, seen.baseline_digest) == (
        Verdict.BASELINE,
        (5,),
        kept.digest,
    )
    other = msgspec.structs.replace(kept, digest="0123456789abcdef")
    later = msgspec.structs.replace(kept, epoch=1, digest="fedcba9876543210")
    seen = adoption(proposal, [adopted, other, later])
    assert (seen.verdict, seen.adopted_by, seen.other_by) == (Verdict.MIXED, (3,), (5,))
