"""What a UAV's outcome proves (its own reached targets) and what it only hints at (a
teammate's)."""

from __future__ import annotations

from fleet.mission import claims
from fleet.mission.messages import TargetOutcome
from fleet.mission.phase import Phase


def test_an_outcome_proves_its_own_uavs_reached_targets_only() -> None:
    outcome = TargetOutcome(3, 74, 2, Phase.REACHED, reached={0: 74, 1: 112, 2: 74})
    assert claims.own_claims(outcome) == {0: 74, 2: 74}
    assert claims.hints(outcome) == {1: 112}
    failed = TargetOutcome(3, 74, 2, Phase.FAILED, "no route", reached={0: 74})
    assert claims.own_claims(failed) == {0: 74}


def test_a_lie_about_a_teammate_is_not_believed_until_the_teammate_says_so() -> None:
    lie = TargetOutcome(3, 74, None, Phase.REACHED, reached={1: 112})
    assert claims.reached_by([lie]) == {}
    assert claims.unconfirmed([lie]) == {112}
    own = TargetOutcome(3, 112, 1, Phase.REACHED, reached={1: 112})
    assert claims.reached_by([lie, own]) == {1: 112}
    assert claims.unconfirmed([lie, own]) == set()


def test_an_older_copy_of_a_uavs_outcome_does_not_replace_a_newer_one() -> None:
    first = TargetOutcome(3, 74, 0, Phase.REACHED, reached={0: 74})
    second = TargetOutcome(3, 74, 2, Phase.REACHED, reached={0: 74, 2: 74})
    assert claims.newer(None, first) and claims.newer(first, second)
    assert not claims.newer(second, first)
    failed = TargetOutcome(3, 74, 2, Phase.FAILED, "lost", reached={0: 74})
    assert claims.newer(first, failed)
