"""Re-planning after the commitment: a function of epoch 0 and the released set; every
survivor may take orphans, at the ends of the queues."""

from __future__ import annotations

import itertools

import pytest

from fleet.consensus.replan import candidates, missing_times, orphaned_targets, replan
from fleet.mission.messages import AssignmentReport
from tests.support.greedy_report import greedy_report

# 3 UAVs, 2 targets: 74 and 112 hold targets, 200 is idle. Legs of 100 s.
TIMES: dict[int, tuple[float | None, ...]] = {
    74: (10.0, 50.0),
    112: (40.0, 20.0),
    200: (30.0, 35.0),
}


LEGS = [[0.0, 100.0], [100.0, 0.0]]


def base_report(times: dict[int, tuple[float | None, ...]] = TIMES) -> AssignmentReport:
    return greedy_report(times)


def test_the_idle_uav_takes_the_target_of_a_released_holder() -> None:
    base = base_report()
    assert base.pairs == {74: 0, 112: 1}
    assert orphaned_targets(base, {112}) == (1,)
    assert candidates(base, {112}) == (74, 200)  # every survivor may take orphans
    plan = replan(base, TIMES, {112}, LEGS)
    assert plan.pairs == {74: 0, 200: 1}
    assert plan.epoch == 1 and plan.released == (112,)
    assert plan.unassigned == ()
    assert plan.digest != base.digest


def test_releasing_an_idle_uav_changes_no_pair_but_the_epoch() -> None:
    plan = replan(base_report(), TIMES, {200}, LEGS)
    assert plan.pairs == {74: 0, 112: 1} and plan.epoch == 1


def test_with_no_idle_uav_left_a_holder_queues_the_orphan_after_its_own() -> None:
    plan = replan(base_report(), TIMES, {112, 200}, LEGS)
    assert plan.pairs == {74: 0} and plan.unassigned == () and plan.epoch == 2
    assert plan.plan.queues[74] == (0, 1)
    assert plan.plan.arrivals[74] == (10.0, 110.0)


def test_the_orphan_goes_where_it_is_reached_earliest() -> None:
    # 74 finishes target 0 at 10 s and would reach target 1 at 110 s; 200 at 35 s.
    assert replan(base_report(), TIMES, {112}, LEGS).plan.queues[200] == (1,)
    slow = {**TIMES, 200: (30.0, 150.0)}
    plan = replan(base_report(slow), slow, {112}, LEGS)
    assert plan.plan.queues[74] == (0, 1) and plan.plan.queues[200] == ()


def test_with_no_survivor_able_to_reach_it_the_orphan_is_unserved_with_the_reason() -> None:
    times: dict[int, tuple[float | None, ...]] = {74: (10.0, None), 112: (40.0, 20.0)}
    plan = replan(base_report(times), times, {112}, LEGS)
    assert plan.unassigned == (1,)
    assert plan.unserved == {1: "no surviving UAV has an approach time to it"}


def test_a_candidate_without_a_time_for_the_orphan_is_not_given_it() -> None:
    times = {**TIMES, 200: (30.0, None)}
    plan = replan(base_report(times), times, {112}, LEGS)
    assert plan.plan.queues[200] == () and plan.plan.queues[74] == (0, 1)


LEGS3 = [[0.0 if i == j else 50.0 + i + j for j in range(3)] for i in range(3)]


def test_the_outcome_does_not_depend_on_the_order_losses_were_seen() -> None:
    times: dict[int, tuple[float | None, ...]] = {
        1: (5.0, 9.0, 9.0),
        2: (9.0, 5.0, 9.0),
        3: (8.0, 8.0, 8.0),
        4: (7.0, 6.0, 9.0),
    }
    base = base_report(times)
    plans = {
        (lost := replan(base, times, order, LEGS3)).digest: lost
        for order in itertools.permutations([1, 2])
    }
    assert len(plans) == 1
    assert len({str(plan.plan) for plan in plans.values()}) == 1


def test_missing_candidate_times_are_named_and_refused() -> None:
    base = base_report()
    partial = {74: TIMES[74], 112: TIMES[112]}
    assert missing_times(base, partial, {112}) == (200,)
    assert missing_times(base, partial, set()) == ()  # nothing orphaned: nothing needed
    with pytest.raises(KeyError, match="200"):
        replan(base, partial, {112}, LEGS)


def test_released_uavs_outside_the_team_are_ignored() -> None:
    plan = replan(base_report(), TIMES, {999}, LEGS)
    assert plan.epoch == 0 and plan.digest == base_report().digest


# ---- a finished survivor: the last resort -------------------------------------------
SLOW = {**TIMES, 200: (30.0, 150.0)}  # 74 would reach target 1 first (110 s), 200 at 150 s


def test_a_finished_survivor_is_not_handed_an_orphan_another_survivor_can_reach() -> None:
    plan = replan(base_report(SLOW), SLOW, {112}, LEGS, finished={74})
    assert plan.plan.queues == {74: (0,), 200: (1,)}
    assert plan.finished == (74,)
    assert plan.digest != replan(base_report(SLOW), SLOW, {112}, LEGS).digest


def test_a_finished_survivor_takes_an_orphan_nobody_else_can_reach() -> None:
    times = {**TIMES, 200: (30.0, None)}
    plan = replan(base_report(times), times, {112}, LEGS, finished={74})
    assert plan.plan.queues == {74: (0, 1), 200: ()} and plan.unassigned == ()


def test_only_finished_survivors_left_share_the_orphans_by_the_append_rule() -> None:
    plan = replan(base_report(SLOW), SLOW, {112}, LEGS, finished={74, 200})
    assert plan.plan.queues == {74: (0, 1), 200: ()}
    assert plan.unassigned == ()


def test_finished_uavs_change_nothing_without_orphans_or_outside_the_survivors() -> None:
    base = base_report()
    assert (
        replan(base, TIMES, {200}, LEGS, finished={74}).digest
        == replan(base, TIMES, {200}, LEGS).digest
    )
    gone = replan(base, TIMES, {112}, LEGS, finished={112})
    assert gone.finished == () and gone.digest == replan(base, TIMES, {112}, LEGS).digest
