"""Re-planning after the commitment: a function of epoch 0 and the released set."""

from __future__ import annotations

import itertools

import pytest

from fleet.consensus.assignment import greedy_assign, results_digest
from fleet.consensus.replan import candidates, missing_times, orphaned_targets, replan
from fleet.mission.messages import AssignmentReport

# 3 UAVs, 2 targets: 74 and 112 hold targets, 200 is idle.
TIMES: dict[int, tuple[float | None, ...]] = {
    74: (10.0, 50.0),
    112: (40.0, 20.0),
    200: (30.0, 35.0),
}


def base_report(times: dict[int, tuple[float | None, ...]] = TIMES) -> AssignmentReport:
    outcome = greedy_assign(times, len(next(iter(times.values()))))
    return AssignmentReport(
        mission=1,
        uav=74,
        target=outcome.pairs.get(74),
        pairs=dict(outcome.pairs),
        unassigned=outcome.unassigned_targets,
        team=tuple(sorted(times)),
        digest=results_digest(times),
    )


def test_the_idle_uav_takes_the_target_of_a_released_holder() -> None:
    base = base_report()
    assert base.pairs == {74: 0, 112: 1}
    assert orphaned_targets(base, {112}) == (1,)
    assert candidates(base, {112}) == (200,)
    plan = replan(base, TIMES, {112})
    assert plan.pairs == {74: 0, 200: 1}
    assert plan.epoch == 1 and plan.released == (112,)
    assert plan.unassigned == ()
    assert plan.digest != base.digest


def test_releasing_an_idle_uav_changes_no_pair_but_the_epoch() -> None:
    plan = replan(base_report(), TIMES, {200})
    assert plan.pairs == {74: 0, 112: 1} and plan.epoch == 1


def test_with_no_candidate_left_the_orphan_is_unassigned() -> None:
    plan = replan(base_report(), TIMES, {112, 200})
    assert plan.pairs == {74: 0} and plan.unassigned == (1,) and plan.epoch == 2


def test_a_candidate_without_a_time_for_the_orphan_is_not_given_it() -> None:
    times = {**TIMES, 200: (30.0, None)}
    plan = replan(base_report(times), times, {112})
    assert plan.pairs == {74: 0} and plan.unassigned == (1,)


def test_the_outcome_does_not_depend_on_the_order_losses_were_seen() -> None:
    times: dict[int, tuple[float | None, ...]] = {
        1: (5.0, 9.0, 9.0),
        2: (9.0, 5.0, 9.0),
        3: (8.0, 8.0, 8.0),
        4: (7.0, 6.0, 9.0),
    }
    base = base_report(times)
    plans = {
        (lost := replan(base, times, order)).digest: lost
        for order in itertools.permutations([1, 2])
    }
    assert len(plans) == 1


def test_missing_candidate_times_are_named_and_refused() -> None:
    base = base_report()
    partial = {74: TIMES[74], 112: TIMES[112]}
    assert missing_times(base, partial, {112}) == (200,)
    assert missing_times(base, partial, set()) == ()  # nothing orphaned: nothing needed
    with pytest.raises(KeyError, match="200"):
        replan(base, partial, {112})


def test_released_uavs_outside_the_team_are_ignored() -> None:
    plan = replan(base_report(), TIMES, {999})
    assert plan.epoch == 0 and plan.digest == base_report().digest
