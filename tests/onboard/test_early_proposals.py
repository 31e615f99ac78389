"""A proposal that arrives before its mission (onboard.early_proposals): kept, a few at
most, and checked when the mission arrives, as one heard after it; what is not kept is
counted (`bus_proposal_no_mission` in the UAV's state)."""

from __future__ import annotations

from fleet.consensus.proposal import ProposalRefused
from fleet.mission.messages import MISSION_MANAGER, MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from fleet.transport.bus_codec import DROPPED
from onboard.core import OnboardCore
from onboard.early_proposals import MAX_KEPT, PER_PROPOSER, EarlyProposals
from tests.onboard.core_harness import TARGETS, make_core

TEAM = (74, 112)
TIMES_74 = (10.0, 90.0, 95.0)


def _proposal(mission: int, proposer: int = MISSION_MANAGER, digest: str = "d") -> PlanProposal:
    return PlanProposal(
        mission=mission,
        proposer=proposer,
        digest=digest,
        objective=Objective.MIN_SUM,
        queues={74: (0, 2), 112: (1,)},
    )


def _no_mission() -> int:
    return DROPPED.counts().get(ProposalRefused.NO_MISSION, 0)


def test_a_proposer_floods_mission_ids_and_pushes_out_its_own_only() -> None:
    early = EarlyProposals()
    assert early.keep(_proposal(3, proposer=5)) == []
    for mission in range(4, 4 + PER_PROPOSER + 3):  # the ground floods later ids
        early.keep(_proposal(mission))
    assert len(early) == PER_PROPOSER + 1  # its newest, and UAV 5's, still kept
    # A proposer's later plan for one mission takes its earlier one's place, uncounted.
    assert early.keep(_proposal(3, proposer=5, digest="e")) == []
    taken, stale = early.take(3)
    assert [p.digest for p in taken] == ["e"] and stale == []
    # In all, never more than MAX_KEPT: the first kept goes first.
    many = EarlyProposals(per_proposer=100)
    dropped = [p for mission in range(1, MAX_KEPT + 4) for p in many.keep(_proposal(mission))]
    assert len(many) == MAX_KEPT and [p.mission for p in dropped] == [1, 2, 3]
    # A mission that starts supersedes the older ones kept; later ones stay.
    taken, stale = many.take(10)
    assert [p.mission for p in taken] == [10]
    assert [p.mission for p in stale] == list(range(4, 10))
    assert len(many) == MAX_KEPT + 3 - 10


def _digest_of_the_round() -> str:
    """The results digest UAV 112 decides mission 1 on (its own result and 74's): what a
    proposer that solved from them puts in its plan."""
    twin, _ = make_core(uav=112)
    _start(twin, proposals_s=0.0)
    assert twin.round is not None
    used = {uav: result.times for uav, result in twin.round.results.items()}
    assert set(used) == set(TEAM)
    return twin.round.results_digest(used)


def _start(core: OnboardCore, proposals_s: float) -> None:
    core.on_alive(74, True, 0.0)
    mission = MissionTargets(
        mission=1, team=TEAM, targets=TARGETS, objective=Objective.MIN_SUM, proposals_s=proposals_s
    )
    core.on_targets(mission, 1.0)
    core.on_result(UavResult(1, 74, TIMES_74), 1.05)
    core.tick(1.1)


def test_a_proposal_heard_before_its_mission_is_checked_and_decided_with_when_it_arrives() -> None:
    digest = _digest_of_the_round()
    core, _ = make_core(uav=112)
    before = _no_mission()
    core.on_proposal(_proposal(1, digest=digest), 0.5)  # before the mission
    core.on_proposal(_proposal(1, proposer=74, digest=digest), 0.5)  # 74 is not named
    assert core.round is None
    _start(core, proposals_s=5.0)
    mission_round = core.round
    assert mission_round is not None
    # Checked as it would be heard now: the ground's kept, 74's refused for want of the
    # right (the mission names no proposer: the ground's plan only).
    assert set(mission_round.proposals) == {MISSION_MANAGER}
    core.tick(1.2)
    committed = mission_round.committed
    assert committed is not None  # decided at once: the ground's awaited plan was held
    assert mission_round.refused_proposals == {}  # a plan of the round's own inputs
    assert _no_mission() == before  # nothing dropped for want of its mission


def test_proposals_for_a_mission_not_held_are_counted_when_dropped() -> None:
    core, _ = make_core(uav=112)
    _start(core, proposals_s=0.0)
    assert core.round is not None and core.round.committed is not None
    before = _no_mission()
    core.on_proposal(_proposal(1), 2.0)  # its own mission's, after the decision: no drop
    assert _no_mission() == before
    # Later missions 2-5: the ground's newest PER_PROPOSER kept, the older ones counted.
    for mission in range(2, 6):
        core.on_proposal(_proposal(mission), 2.0)
    assert _no_mission() == before + 4 - PER_PROPOSER
    # Mission 5 starts: mission 4's kept proposal is superseded (counted), 5's taken.
    core.on_targets(MissionTargets(mission=5, team=TEAM, targets=TARGETS), 3.0)
    assert _no_mission() == before + 4 - PER_PROPOSER + 1
    assert core.round is not None and core.round.mission == 5
    assert set(core.round.proposals) == {MISSION_MANAGER}
    # An older mission's proposal: counted.
    core.on_proposal(_proposal(1), 4.0)
    assert _no_mission() == before + 4 - PER_PROPOSER + 2


def test_a_proposal_for_the_mission_held_after_the_decision_is_counted_late() -> None:
    """Entitled and for the mission held, but heard after this UAV decided: it changes
    nothing, and is counted (`bus_proposal_late` in the UAV's state) and logged."""
    core, _ = make_core(uav=112)
    _start(core, proposals_s=0.0)
    assert core.round is not None and core.round.committed is not None
    committed = core.round.committed
    counts = DROPPED.counts()
    late = counts.get(ProposalRefused.LATE, 0)
    no_right = counts.get(ProposalRefused.NO_RIGHT, 0)
    core.on_proposal(_proposal(1), 2.0)  # the ground's: entitled, late
    assert DROPPED.counts().get(ProposalRefused.LATE, 0) == late + 1
    assert core.round.committed is committed and not core.round.proposals
    # One without the right is counted for that, not as late.
    core.on_proposal(_proposal(1, proposer=74), 2.0)
    counts = DROPPED.counts()
    assert counts.get(ProposalRefused.LATE, 0) == late + 1
    assert counts.get(ProposalRefused.NO_RIGHT, 0) == no_right + 1
    # Before the decision it is kept, not counted.
    early, _ = make_core(uav=112)
    _start(early, proposals_s=5.0)
    assert early.round is not None and early.round.committed is None
    early.on_proposal(_proposal(1, digest="other"), 1.2)
    assert set(early.round.proposals) == {MISSION_MANAGER}
    assert DROPPED.counts().get(ProposalRefused.LATE, 0) == late + 1
