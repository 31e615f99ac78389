"""A mission changed in flight (fleet.consensus.mission_change): the next revision, what
a UAV takes as one, and the re-plan of what is left (fleet.consensus.replan)."""

from __future__ import annotations

import msgspec
import pytest

from fleet.consensus.legs import leg_times
from fleet.consensus.mission_change import (
    added_targets,
    change_digest,
    change_problem,
    estimated_times,
    first_revision,
    next_revision,
)
from fleet.consensus.replan import replan
from fleet.mission.messages import AssignmentReport, MissionTargets, Target, UavResult

THREE = (Target(42.37, -71.08, 120.0), Target(42.35, -71.10, 130.0), Target(42.36, -71.05, 90.0))
MISSION = MissionTargets(mission=7, team=(101, 102), targets=THREE)
NEAR_101 = Target(42.3801, -71.0801, 100.0)
NEAR_102 = Target(42.3501, -71.1001, 100.0)


def test_the_next_revision_appends_and_removes_and_keeps_every_index() -> None:
    one = next_revision(MISSION, added=(NEAR_101,), removed=(1,))
    assert (one.revision, one.removed, one.planned) == (1, (1,), 3)
    assert one.targets[:3] == THREE and one.targets[3] == NEAR_101
    two = next_revision(one, added=(NEAR_102,), removed=(3,))
    assert (two.revision, two.removed, two.planned, len(two.targets)) == (2, (1, 3), 3, 5)
    assert added_targets(two) == (4,)  # 3 was added, then removed
    assert first_revision(two) == MISSION
    with pytest.raises(ValueError, match="removed already"):
        next_revision(two, removed=(1,))
    with pytest.raises(ValueError, match="not one of"):
        next_revision(two, removed=(9,))


def test_a_later_revision_must_extend_the_one_held() -> None:
    one = next_revision(MISSION, added=(NEAR_101,))
    assert change_problem(MISSION, one) is None
    assert "not later" in (change_problem(one, one) or "")
    moved = msgspec.structs.replace(one, targets=(NEAR_102, *one.targets[1:]))
    assert "indexes never change" in (change_problem(MISSION, moved) or "")
    without_0 = next_revision(one, removed=(0,))
    back = msgspec.structs.replace(without_0, revision=3, removed=())
    assert "puts back" in (change_problem(without_0, back) or "")
    other_team = msgspec.structs.replace(one, team=(101,))
    assert "team" in (change_problem(MISSION, other_team) or "")


def test_an_added_targets_time_is_estimated_from_where_the_uav_planned() -> None:
    result = UavResult(7, 101, (10.0, 20.0, 30.0), airspeed=20.0, lat=42.38, lon=-71.08)
    (near,) = estimated_times(result, (*THREE, NEAR_101), (3,))
    assert near is not None and 0.0 < near < 2.0  # about 14 m at 20 m/s
    silent = UavResult(7, 102, (10.0, 20.0, 30.0))
    assert estimated_times(silent, (*THREE, NEAR_101), (3,)) == (None,)


def test_the_change_digest_names_the_revision() -> None:
    one = next_revision(MISSION, added=(NEAR_101,))
    assert change_digest("d", MISSION) == "d"
    assert change_digest("d", one) != "d"
    assert change_digest("d", one) != change_digest("d", next_revision(one, removed=(0,)))


def base_plan() -> AssignmentReport:
    return AssignmentReport(
        7, 101, 0, {101: 0, 102: 1}, (), (101, 102), "base",
        queues={101: (0, 2), 102: (1,)},
    )  # fmt: skip


def test_a_removed_target_leaves_every_queue_and_an_added_one_goes_where_it_is_reached_first() -> (
    None
):
    changed = next_revision(MISSION, added=(NEAR_102,), removed=(2,))
    times = {
        101: (10.0, 50.0, 30.0, 60.0),
        102: (50.0, 10.0, 40.0, 12.0),
    }
    legs = leg_times(changed.targets)
    plan = replan(base_plan(), times, (), legs, removed=changed.removed, added=(3,))
    assert plan.plan.queues[101] == (0,)  # 2 removed: never flown
    assert 3 in plan.plan.queues[102]  # added beside 102's target: 102 flies it
    assert 2 not in plan.unserved and not plan.unserved
    # Removed and released at once: the released UAV's queue less the removed target.
    gone = replan(base_plan(), times, (101,), legs, removed=(2,), added=(3,))
    assert sorted(gone.plan.queues[102]) == [0, 1, 3]
