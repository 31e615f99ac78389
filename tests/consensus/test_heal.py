"""Two committed plans of one mission after a partition heals (fleet.consensus.heal):
the one built from more results wins on every UAV, whatever the order they meet in, and
a UAV on the other re-bases onto it, keeping what was reached."""

from __future__ import annotations

from itertools import permutations

from fleet.consensus.heal import Rank, rank
from fleet.consensus.mission_round import MissionRound
from fleet.mission.messages import (
    AssignmentHeader,
    AssignmentReport,
    MissionTargets,
    Target,
    UavResult,
)

TEAM = (101, 102, 103, 104)
TARGETS = MissionTargets(
    mission=9,
    team=TEAM,
    targets=tuple(Target(35.7 + 0.01 * i, -120.8 + 0.01 * i, 600.0) for i in range(4)),
    deadline_s=10.0,
)
TIMES = {
    101: (10.0, 60.0, 80.0, 90.0),
    102: (70.0, 15.0, 85.0, 95.0),
    103: (75.0, 65.0, 12.0, 70.0),
    104: (90.0, 80.0, 60.0, 14.0),
}


def _result(uav: int) -> UavResult:
    return UavResult(mission=9, uav=uav, times=TIMES[uav])


def _standing(uav: int, basis: str, reached: tuple[int, ...] = ()) -> UavResult:
    times = tuple(t + 5.0 for t in TIMES[uav])
    return UavResult(mission=9, uav=uav, times=times, basis=basis, reached=reached)


def _side(uav: int, held: tuple[int, ...]) -> MissionRound:
    """`uav`'s round, committed on the results of `held` alone (the rest cut off)."""
    mission_round = MissionRound(TARGETS, uav, started=0.0, resolving=True)
    for other in held:
        mission_round.add_result(_result(other))
    mission_round.decide(set(held))
    return mission_round


def _healed_strong_side() -> MissionRound:
    """103, committed on all four results, counted 101 and 102 out (the cut) and back in
    (the heal); their standings never came, so it committed the epoch's append plan."""
    strong = _side(103, TEAM)
    strong.release((101, 102))
    assert strong.replan(10.0) is None  # waiting for 103's and 104's standings
    assert strong.expire(20.0) is not None
    assert strong.rejoin((101, 102))
    assert strong.replan(30.0) is None  # waiting for all four standings
    report = strong.expire(40.0)
    assert report is not None and report.epoch == 4 and report.basis is None
    return strong


def test_the_plan_built_from_more_results_wins_and_ties_go_to_the_team_sorting_first() -> None:
    assert rank(TEAM, (101, 102)) is Rank.STRONGER
    assert rank((101, 102), TEAM) is Rank.WEAKER
    assert rank((102, 101), (101, 102)) is Rank.SAME
    assert rank((101, 102), (103, 104)) is Rank.STRONGER
    assert rank((103, 104), (101, 102)) is Rank.WEAKER
    # A total order: of any plans, every UAV picks the same one, whatever it met first.
    teams = [(101, 102), (103, 104), (101, 103, 104), TEAM, (102, 103)]
    for order in permutations(teams):
        best = order[0]
        for team in order[1:]:
            if rank(team, best) is Rank.STRONGER:
                best = team
        assert best == TEAM


def test_the_two_sides_of_a_healed_split_converge_on_the_plan_of_all_four_results() -> None:
    strong = _healed_strong_side()
    strong_report = strong.committed
    assert strong_report is not None
    weak = _side(101, (101, 102))  # 103's and 104's results never reached 101
    assert weak.committed is not None and weak.committed.team == (101, 102)
    weak.target_reached(101, 0)  # flown under its own plan: a fact
    # Each side ranks the other's plan alike; only the weak side moves.
    assert strong.rank_of(weak.committed) is Rank.WEAKER
    assert strong.rebase(weak.committed) is None
    assert weak.rank_of(strong_report) is Rank.STRONGER
    rebased = weak.rebase(strong_report)
    assert rebased is not None and weak.base is None
    assert (rebased.digest, rebased.queues, rebased.uav) == (
        strong_report.digest,
        strong_report.queues,
        101,
    )
    assert weak.reached_targets == {0: 101}  # what was reached stays reached
    assert weak.released == strong.released == set()
    # 101 now stands for the winner's append plan: its standing counts it in there.
    assert weak.stands_for() is weak.committed
    basis = strong_report.digest
    strong.add_standing(_standing(101, basis, reached=(0,)))
    strong.add_standing(_standing(102, basis))
    strong.add_standing(_standing(103, basis))
    assert strong.resolve_ready() is None  # 104's still missing
    strong.add_standing(_standing(104, basis))
    resolved = strong.resolve_ready()
    assert resolved is not None and resolved.basis == basis and resolved.epoch == 4
    assert 0 not in {t for q in resolved.queues.values() for t in q}  # reached: not again
    adopted = weak.adopt_resolved(resolved)
    assert adopted is not None and adopted.digest == resolved.digest
    assert weak.committed is not None and strong.committed is not None
    assert weak.committed.digest == strong.committed.digest


def test_a_settled_uav_lets_through_a_report_of_a_plan_built_on_another_team() -> None:
    weak = _side(101, (101, 102))
    settled = weak.settled(aborted=False)
    same = AssignmentHeader(mission=9, uav=102, team=(101, 102))
    assert settled.covers(same)
    assert not settled.covers(AssignmentHeader(mission=9, uav=103, epoch=4, team=TEAM))
    assert settled.covers(AssignmentHeader(mission=9, uav=103))  # no team said: as before


def test_a_report_of_another_mission_is_never_ranked() -> None:
    weak = _side(101, (101, 102))
    strong = _side(103, TEAM).committed
    assert strong is not None
    other = AssignmentReport(
        mission=8, uav=103, target=0, pairs={103: 0}, unassigned=(), team=TEAM, digest="d"
    )
    assert weak.rank_of(other) is Rank.SAME and weak.rebase(other) is None


def test_the_side_rebased_onto_a_plan_built_without_it_is_counted_in_and_takes_part() -> None:
    """A 2|2 split during the results' fan-out: each side committed on its own two, and
    the tie goes to (101, 102). 103 and 104 re-base onto a plan that holds nothing for
    them; counted in (as a UAV back from a loss is), the next epoch is solved again from
    all four standings, on every UAV of the winning side alike."""
    winners = [_side(101, (101, 102)), _side(102, (101, 102))]
    loser = _side(103, (103, 104))
    theirs = winners[0].committed
    assert theirs is not None and loser.rank_of(theirs) is Rank.STRONGER
    rebased = loser.rebase(theirs)
    assert rebased is not None
    assert MissionRound.survivors(rebased) == (101, 102)  # 103 and 104 take no part
    loser.target_reached(103, 2)  # flown under its own plan before the heal
    plans = []
    for winner in winners:
        assert winner.joinable(103) and winner.joinable(104) and not winner.joinable(101)
        assert winner.rejoin((103,)) and winner.rejoin((104,))
        assert not winner.joinable(103) and not winner.rejoin((103,))  # counted once
        assert winner.replan(50.0) is None  # waiting for every standing, the joined too
        fallback = winner.awaiting
        assert fallback is not None and MissionRound.survivors(fallback) == TEAM
        assert fallback.queues == theirs.queues  # the append plan: epoch 0's, nothing moved
        assert winner.missing_standings() == TEAM
        for uav in TEAM:
            winner.add_standing(_standing(uav, fallback.digest, reached=(2,) if uav == 103 else ()))
        resolved = winner.resolve_ready()
        assert resolved is not None and resolved.basis == fallback.digest
        plans.append(resolved)
    assert plans[0].digest == plans[1].digest and plans[0].queues == plans[1].queues
    plan = plans[0]
    assert plan.team == (101, 102) and plan.epoch == 4  # counted out once, back once: 2 each
    queued = sorted(t for q in plan.queues.values() for t in q)
    assert queued == [0, 1, 3]  # 2 reached: not again; nothing dropped
    assert plan.queues.get(104)  # a re-based UAV flies again
    # The rebased UAV follows the resolved plan, and its going is a new epoch again.
    followed = loser.follow(plan)
    assert followed is not None and followed.digest == plan.digest
    assert winners[0].release((104,))
