"""Tests of one UAV's round of a mission (fleet.consensus.mission_round), pure and in-process."""

from __future__ import annotations

from fleet.consensus.assignment import results_digest
from fleet.consensus.mission_round import FETCH_INTERVAL, MissionRound, Settled, assignment_problem
from fleet.mission.messages import (
    AssignmentHeader,
    AssignmentReport,
    MissionTargets,
    Target,
    UavResult,
)

TARGETS = MissionTargets(
    mission=7,
    team=(74, 112, 200),
    targets=(Target(35.7, -120.8, 600.0), Target(35.8, -120.7, 600.0)),
    deadline_s=10.0,
)
ALL = {74, 112, 200}
# 74 is fastest to target 0, 112 to target 1; 200 is slow to both.
TIMES = {74: (10.0, 50.0), 112: (40.0, 20.0), 200: (90.0, 95.0)}


def result(uav: int, mission: int = 7) -> UavResult:
    return UavResult(mission=mission, uav=uav, times=TIMES[uav])


def round_of(uav: int = 74, started: float = 100.0) -> MissionRound:
    return MissionRound(targets=TARGETS, own_id=uav, started=started)


def test_results_for_another_mission_or_stranger_or_wrong_length_are_refused() -> None:
    mission_round = round_of()
    assert not mission_round.add_result(result(112, mission=8))
    assert not mission_round.add_result(UavResult(mission=7, uav=999, times=(1.0, 2.0)))
    assert not mission_round.add_result(UavResult(mission=7, uav=112, times=(1.0,)))
    assert mission_round.results == {}
    assert mission_round.add_result(result(112))
    assert set(mission_round.results) == {112}


def test_not_ready_without_its_own_result_even_past_the_deadline() -> None:
    mission_round = round_of()
    mission_round.add_result(result(112))
    mission_round.add_result(result(200))
    assert not mission_round.ready(now=1e9, alive=ALL)
    assert not mission_round.should_fetch(now=1e9, alive=ALL)


def test_ready_once_every_live_teammate_answered() -> None:
    mission_round = round_of()
    mission_round.add_result(result(74))
    mission_round.add_result(result(112))
    assert mission_round.missing(ALL) == {200}
    assert not mission_round.ready(now=101.0, alive=ALL)
    # 200 is no longer alive: nothing is missing, no need to wait for the deadline.
    assert mission_round.expected({74, 112}) == {74, 112}
    assert mission_round.ready(now=101.0, alive={74, 112})


def test_the_own_uav_is_always_expected_even_when_not_seen_alive() -> None:
    assert round_of(74).expected(alive={112}) == {74, 112}


def test_ready_at_the_deadline_with_what_it_holds() -> None:
    mission_round = round_of(started=100.0)
    mission_round.add_result(result(74))
    assert not mission_round.ready(now=109.9, alive=ALL)
    assert mission_round.ready(now=110.0, alive=ALL)


def test_fetches_missing_results_at_most_every_interval() -> None:
    mission_round = round_of()
    mission_round.add_result(result(74))
    assert mission_round.should_fetch(now=100.0, alive=ALL)
    mission_round.last_fetch = 100.0
    assert not mission_round.should_fetch(now=100.0 + FETCH_INTERVAL / 2, alive=ALL)
    assert mission_round.should_fetch(now=100.0 + FETCH_INTERVAL, alive=ALL)
    mission_round.add_result(result(112))
    mission_round.add_result(result(200))
    assert not mission_round.should_fetch(now=200.0, alive=ALL)


def test_decide_runs_the_greedy_on_the_live_results_and_commits() -> None:
    mission_round = round_of(112)
    for uav in ALL:
        mission_round.add_result(result(uav))
    report = mission_round.decide(alive={74, 112})  # 200 died after answering
    assert mission_round.committed == report
    assert report.mission == 7
    assert report.uav == 112
    assert report.target == 1
    assert report.pairs == {74: 0, 112: 1}
    assert report.unassigned == ()
    assert report.team == (74, 112)
    assert report.digest == results_digest({74: TIMES[74], 112: TIMES[112]})
    assert report.eta_s == 20.0
    # Committed: never ready or fetching again, and a teammate's report is not adopted.
    assert not mission_round.ready(now=1e9, alive=ALL)
    assert not mission_round.should_fetch(now=1e9, alive=ALL)
    assert mission_round.adopt(report, ALL, 0.1) is None


def test_an_idle_uav_commits_to_no_target() -> None:
    mission_round = round_of(200)
    for uav in ALL:
        mission_round.add_result(result(uav))
    report = mission_round.decide(alive=ALL)
    assert report.target is None
    assert report.eta_s is None


def test_adopting_a_teammates_commitment_takes_its_pairs_and_own_eta() -> None:
    deciding = round_of(74)
    for uav in ALL:
        deciding.add_result(result(uav))
    theirs = deciding.decide(alive=ALL)

    late = round_of(112)
    late.add_result(result(112))
    adopted = late.adopt(theirs, ALL, 0.1)
    assert adopted is not None
    assert late.committed == adopted
    assert adopted.uav == 112
    assert adopted.target == 1
    assert (adopted.pairs, adopted.team, adopted.digest) == (
        theirs.pairs,
        theirs.team,
        theirs.digest,
    )
    assert adopted.eta_s == TIMES[112][1]


def test_adopting_without_its_own_result_takes_the_plans_predicted_arrival() -> None:
    deciding = round_of(74)
    for uav in ALL:
        deciding.add_result(result(uav))
    adopted = round_of(112).adopt(deciding.decide(alive=ALL), ALL, 0.1)
    assert adopted is not None
    assert adopted.target == 1
    assert adopted.eta_s == TIMES[112][1] == adopted.arrivals[112][0]


def test_a_commitment_for_another_mission_is_not_adopted() -> None:
    other = MissionRound(
        targets=MissionTargets(mission=8, team=TARGETS.team, targets=TARGETS.targets),
        own_id=74,
        started=0.0,
    )
    for uav in ALL:
        other.add_result(result(uav, mission=8))
    mission_round = round_of(112)
    assert mission_round.adopt(other.decide(alive=ALL), ALL, 0.1) is None
    assert mission_round.committed is None


def test_a_thin_commitment_is_refused_while_this_uav_still_computes() -> None:
    alone = round_of(74)
    alone.add_result(result(74))
    thin = alone.decide(alive=ALL)  # 74 committed on its own result alone
    computing = round_of(112, started=0.0)
    computing.add_result(result(74))  # holds nothing 74 did not use...
    assert computing.adopt(thin, ALL, now=5.0) is None  # ...but computes its own
    assert computing.thinner(thin, ALL, now=5.0) == {112}
    joining = round_of(200, started=0.0)
    assert joining.adopt(thin, ALL, now=0.05) is not None  # committed before it joined


def test_a_commitment_without_a_held_teammate_result_is_refused() -> None:
    alone = round_of(74)
    alone.add_result(result(74))
    thin = alone.decide(alive=ALL)
    holding = round_of(112, started=0.0)
    holding.add_result(result(200))
    assert holding.thinner(thin, ALL, now=0.05) == {200}
    assert holding.adopt(thin, ALL, now=0.05) is None


def test_an_assignment_that_cannot_be_this_missions_is_named() -> None:
    def report(pairs: dict[int, int], **extra: object) -> AssignmentReport:
        fields: dict[str, object] = {"target": None, "unassigned": (), "team": (74, 112)}
        fields.update(extra)
        return AssignmentReport(7, 74, pairs=pairs, digest="d", **fields)  # type: ignore[arg-type]

    assert assignment_problem(report({74: 0, 112: 1}), TARGETS) is None
    for bad, why in [
        (report({74: 2}), "has 2"),
        (report({999: 0}), "not a UAV"),
        (report({74: 0, 112: 0}), "same target"),
        (report({}, target=5), "has 2"),
        (report({}, unassigned=(3,)), "beyond"),
        (report({}, team=(74, 999)), "outside"),
    ]:
        problem = assignment_problem(bad, TARGETS)
        assert problem is not None and why in problem, (bad, problem)


def test_after_the_commitment_a_teammates_new_result_does_not_replace_the_one_used() -> None:
    mission_round = round_of()
    for uav in ALL:
        mission_round.add_result(result(uav))
    mission_round.decide(ALL)
    again = UavResult(mission=7, uav=200, times=(1.0, 1.0))  # restarted, planned anew
    assert not mission_round.add_result(again)
    assert mission_round.results[200] == result(200)


def test_each_result_heard_pushes_the_fetch_back_but_not_past_the_deadline() -> None:
    mission_round = round_of(started=100.0)  # deadline 110
    mission_round.add_result(result(74))
    mission_round.last_fetch = 101.0  # its own result published
    mission_round.add_result(result(112))
    mission_round.heard(101.8)
    assert not mission_round.should_fetch(now=102.5, alive=ALL)
    assert mission_round.should_fetch(now=102.8, alive=ALL)
    # Results keep coming: the fetch still comes one interval before the deadline.
    for now in (106.0, 107.5, 108.5, 109.0):
        mission_round.heard(now)
    assert mission_round.should_fetch(now=110.0 - FETCH_INTERVAL, alive=ALL)


def _header(
    uav: int, mission: int = 7, epoch: int = 0, released: tuple[int, ...] = ()
) -> AssignmentHeader:
    return AssignmentHeader(mission=mission, uav=uav, epoch=epoch, released=released)


def test_settled_covers_only_reports_that_change_nothing() -> None:
    mission_round = round_of(74)
    for uav in ALL:
        mission_round.add_result(result(uav))
    waiting = mission_round.settled(aborted=False)
    assert not waiting.covers(_header(112))  # it may adopt it
    assert waiting.covers(_header(74))  # its own, echoed
    assert waiting.covers(_header(112, mission=6))  # an older mission's
    assert not waiting.covers(_header(112, mission=8))  # a newer one may start
    assert mission_round.settled(aborted=True).covers(_header(112))

    mission_round.decide(ALL)
    settled = mission_round.settled(aborted=False)
    assert settled.covers(_header(112))
    assert settled.covers(_header(112, epoch=1, released=(999,)))  # not of the team
    assert not settled.covers(_header(112, epoch=1, released=(200,)))  # a re-plan
    mission_round.release((200,))
    assert mission_round.settled(aborted=False).covers(_header(112, epoch=1, released=(200,)))


def test_settled_without_epoch_zero_takes_later_epochs() -> None:
    mission_round = round_of(112)  # restarted: no result of its own
    report = AssignmentReport(
        mission=7, uav=74, target=0, pairs={74: 0, 112: 1}, unassigned=(),
        team=(74, 112), digest="d", epoch=1, released=(200,),
    )  # fmt: skip
    assert mission_round.follow(report) is None
    assert mission_round.adopt(report, ALL, now=100.1) is not None
    assert mission_round.base is None
    settled = mission_round.settled(aborted=False)
    assert settled.covers(_header(74, epoch=1, released=(200,)))
    assert not settled.covers(_header(74, epoch=2, released=(200,)))


def test_the_decision_uses_the_times_held_even_when_set_around_add_result() -> None:
    """Each result's greedy order and digest bytes are computed as it arrives; results put
    in `results` directly (or replaced there) are prepared at the decision instead, so
    the commitment is always that of the times held."""
    prepared = round_of()
    for uav in ALL:
        prepared.add_result(result(uav))
    direct = round_of()
    direct.results = {uav: result(uav) for uav in ALL}
    swapped = round_of()
    for uav in ALL:
        swapped.add_result(result(uav))
    # 200 became fastest to both targets after its row was prepared.
    swapped.results[200] = UavResult(mission=7, uav=200, times=(1.0, 2.0))
    reports = [r.decide(ALL) for r in (prepared, direct, swapped)]
    assert reports[0] == reports[1]
    assert reports[0].pairs == {74: 0, 112: 1}
    assert reports[2].pairs == {200: 0, 112: 1}
    times = {uav: TIMES[uav] for uav in ALL} | {200: (1.0, 2.0)}
    assert reports[2].digest != reports[0].digest
    fresh = round_of()
    for uav in ALL:
        fresh.add_result(UavResult(mission=7, uav=uav, times=times[uav]))
    assert fresh.decide(ALL) == reports[2]


def test_prepare_computes_the_legs_before_any_result() -> None:
    mission_round = round_of()
    legs = mission_round.prepare()
    assert len(legs) == 2 and legs[0][1] == legs[1][0] > 0.0
    assert mission_round.legs is legs  # the decision uses these, not new ones


def test_a_report_with_more_re_plans_asked_in_changed_air_is_not_covered_by_the_settled() -> None:
    settled = Settled(
        mission=1,
        own_id=112,
        committed=True,
        aborted=False,
        team=frozenset({74, 112}),
        done=frozenset(),
        following=None,
        asked=((74, 1),),
    )
    same = AssignmentHeader(mission=1, uav=74, epoch=1, asked={74: 1})
    more = AssignmentHeader(mission=1, uav=74, epoch=2, asked={74: 2})
    assert settled.covers(same) and not settled.covers(more)
