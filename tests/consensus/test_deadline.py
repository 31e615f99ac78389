"""The consensus deadline follows the team size and the planning budget."""

from __future__ import annotations

import pytest

from fleet.consensus.deadline import MIN_DEADLINE_S, consensus_deadline


def test_a_small_team_keeps_the_thesis_ten_seconds() -> None:
    assert consensus_deadline(2) == MIN_DEADLINE_S


def test_fifty_uavs_get_more_than_ten_seconds_and_more_budget_more_time() -> None:
    assert consensus_deadline(50) > MIN_DEADLINE_S
    assert consensus_deadline(50, plan_budget_s=10.0) > consensus_deadline(50)
    assert consensus_deadline(100) > consensus_deadline(50)


@pytest.mark.parametrize(("size", "budget"), [(0, 2.0), (3, float("nan")), (3, -1.0)])
def test_nonsense_is_refused(size: int, budget: float) -> None:
    with pytest.raises(ValueError, match=r"team|budget"):
        consensus_deadline(size, budget)
