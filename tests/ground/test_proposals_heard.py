"""The ground's check of each proposal heard (fleet.consensus.proposal_review) is the UAVs'
own: the same right, the same validity, the same score as the plan a UAV adopting it
reports; and what the UAVs did with each proposal is read from their digests alone
(ground.proposals_heard), a proposal beaten by another shown as such."""

from __future__ import annotations

import msgspec

from fleet.consensus.mission_round import MissionRound
from fleet.consensus.proposal import Verdict
from fleet.consensus.proposal_review import Check, Score, review_proposals
from fleet.mission.messages import MISSION_MANAGER, MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from ground.proposals_heard import declined, heard_proposals, team_plans
from tests.support.proposal_instance import BETTER
from tests.support.proposal_instance import mission_and_results as instance

#: Every target on UAV 3: valid, and worse than the baseline.
WORSE = {3: (0, 1, 2, 3, 4, 5), 5: ()}


def mission_and_results(proposers: tuple[int, ...] = ()) -> tuple[MissionTargets, list[UavResult]]:
    return instance(20.0, proposers)


def on_board(mission: MissionTargets, results: list[UavResult], own: int) -> MissionRound:
    """UAV `own`'s round, holding every result."""
    mission_round = MissionRound(targets=mission, own_id=own, started=0.0)
    for result in results:
        assert mission_round.add_result(result)
    return mission_round


def proposal(
    mission: MissionTargets, results: list[UavResult], proposer: int, queues: object
) -> PlanProposal:
    mission_round = on_board(mission, results, 3)
    used = {uav: r.times for uav, r in mission_round.results.items()}
    return PlanProposal(
        mission=9,
        proposer=proposer,
        digest=mission_round.results_digest(used),
        objective=Objective.MIN_SUM,
        queues=msgspec.convert(queues, dict[int, tuple[int, ...]]),
    )


def test_a_valid_proposal_scores_what_the_uavs_adopting_it_report() -> None:
    mission, results = mission_and_results()
    better = proposal(mission, results, MISSION_MANAGER, BETTER)
    reviews = review_proposals(mission, {r.uav: r for r in results}, [better])
    review = reviews[MISSION_MANAGER]
    assert review.check is Check.VALID and review.problem is None
    mission_round = on_board(mission, results, 5)
    assert mission_round.add_proposal(better)
    adopted = mission_round.decide({3, 5})
    assert adopted.queues == BETTER
    assert review.score == Score.of_report(adopted)
    assert "valid: last arrival" in review.summary()


def test_a_proposal_the_uavs_refuse_is_refused_and_one_not_checkable_is_said() -> None:
    mission, results = mission_and_results()
    held = {r.uav: r for r in results}
    twice = proposal(mission, results, MISSION_MANAGER, {3: (4, 0, 2), 5: (2, 1, 5, 3)})
    not_named = proposal(mission, results, 3, BETTER)
    reviews = review_proposals(mission, held, [twice, not_named])
    assert reviews[MISSION_MANAGER].check is Check.REFUSED
    assert "target 2 twice" in str(reviews[MISSION_MANAGER].problem)
    assert reviews[3].check is Check.REFUSED and "not the ground" in str(reviews[3].problem)
    assert reviews[3].score is None
    # A teammate's result not heard yet: what the proposal is worth is not said, and
    # the proposer's right still is.
    reviews = review_proposals(mission, {3: held[3]}, [twice, not_named])
    assert reviews[MISSION_MANAGER].check is Check.UNCHECKED
    assert reviews[MISSION_MANAGER].problem == "no result heard yet from UAV 5"
    assert reviews[3].check is Check.REFUSED
    changed = msgspec.structs.replace(mission, revision=1)
    assert review_proposals(changed, held, [twice])[MISSION_MANAGER].check is Check.UNCHECKED


def test_each_proposal_heard_is_judged_from_the_digests_the_uavs_reported() -> None:
    """UAV 3 and the ground both propose; the ground's plan is better, so both UAVs
    adopt it: UAV 3's is shown not adopted, the ground's taken instead, never adopted."""
    mission, results = mission_and_results(proposers=(3, MISSION_MANAGER))
    ground = proposal(mission, results, MISSION_MANAGER, BETTER)
    own = proposal(mission, results, 3, WORSE)
    reports = []
    for uav in (3, 5):
        mission_round = on_board(mission, results, uav)
        assert mission_round.add_proposal(ground) and mission_round.add_proposal(own)
        reports.append(mission_round.decide({3, 5}))
    held = {r.uav: r for r in results}
    proposals = {3: own, MISSION_MANAGER: ground}
    by_uav, by_ground = heard_proposals(mission, held, proposals, reports)
    assert (by_uav.proposer, by_ground.proposer) == (3, MISSION_MANAGER)
    assert by_ground.adoption.verdict is Verdict.ADOPTED
    assert by_ground.adoption.adopted_by == (3, 5)
    assert by_uav.review.check is Check.VALID and by_uav.adoption.verdict is Verdict.OTHER
    assert by_uav.instead == ((MISSION_MANAGER, (3, 5)),)
    said = by_uav.summary()
    assert said.startswith("not adopted: 3, 5 took another plan (the ground's adopted by 3, 5)")
    data = by_uav.to_json()
    assert (data["by"], data["verdict"], data["check"]) == ("UAV 3", "other", "valid")
    assert by_uav.review.score is not None and data["score"] == by_uav.review.score.to_json()
    # The plan the UAVs committed to, once, with its score: the ground's.
    (plan,) = team_plans(reports, 9)
    assert plan["by"] == [3, 5] and plan["digest"] == by_ground.adoption.adopted_digest
    assert plan["score"] == by_ground.to_json()["score"]
    # No decision heard yet: waiting, whatever the check says.
    (waiting, _) = heard_proposals(mission, held, proposals, [])
    assert waiting.adoption.verdict is Verdict.WAITING


def test_named_proposers_whose_result_said_no_are_named_as_declined() -> None:
    """A named UAV whose result said it will not propose is not waited for, and the
    ground says why no proposal came from it; one that said yes, or did not say, or whose
    result is not in yet, is not declined."""
    mission, results = mission_and_results(proposers=(3, 5, MISSION_MANAGER))
    by_uav = {r.uav: r for r in results}
    assert declined(mission, by_uav) == []  # neither said (None)
    by_uav[3] = msgspec.structs.replace(by_uav[3], proposes=False)
    by_uav[5] = msgspec.structs.replace(by_uav[5], proposes=True)
    assert declined(mission, by_uav) == [3]
    assert declined(mission, {5: by_uav[5]}) == []
