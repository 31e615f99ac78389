"""Target sets nobody should fly: duplicates, beyond reach, the far side."""

from __future__ import annotations

import pytest

from fleet.geo.great_circle import great_circle_m
from fleet.mission.messages import Target
from fleet.mission.target_checks import ProblemKind, target_set_problems

HOME = (35.72, -120.76)


def test_a_sane_set_has_no_problem() -> None:
    targets = [Target(35.73, -120.75, 600.0), Target(35.70, -120.79, 600.0)]
    assert target_set_problems(targets, {74: HOME, 112: HOME}) == []


def test_two_targets_within_the_acceptance_radius_are_named() -> None:
    targets = [Target(35.73, -120.75, 600.0), Target(35.71, -120.75, 600.0),
               Target(35.7302, -120.75, 600.0)]  # fmt: skip
    (problem,) = target_set_problems(targets, {})
    assert problem.kind == ProblemKind.DUPLICATE and problem.targets == (0, 2)
    assert str(problem).startswith("targets 0 and 2: 22 m apart")


def test_a_target_5000_km_away_is_beyond_reach() -> None:
    far = Target(35.72, -65.0, 600.0)  # the Atlantic coast
    (problem,) = target_set_problems([Target(35.73, -120.75, 600.0), far], {74: HOME})
    assert problem.kind == ProblemKind.BEYOND_REACH and problem.targets == (1,)
    assert "from the nearest team UAV (74)" in problem.detail


def test_the_antipode_is_on_the_far_side() -> None:
    antipode = Target(-HOME[0], HOME[1] + 180.0, 600.0)
    (problem,) = target_set_problems([antipode], {74: HOME, 112: (35.0, -120.0)})
    assert problem.kind == ProblemKind.FAR_SIDE
    assert great_circle_m(*HOME, antipode.lat, antipode.lon) == pytest.approx(20_015_000, rel=1e-3)


def test_reach_is_measured_from_the_nearest_uav_and_skipped_without_a_fix() -> None:
    target = Target(36.5, -120.76, 600.0)  # ~87 km north of HOME
    assert target_set_problems([target], {74: HOME}, max_reach_m=50_000.0)
    assert not target_set_problems([target], {74: HOME, 112: (36.4, -120.76)}, 50_000.0)
    assert not target_set_problems([target], {}, 50_000.0)
