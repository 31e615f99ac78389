"""Which of two committed plans of one mission the team keeps once a partition heals.

A team split while its epoch-0 results were still being sent can commit twice: each
side on the results it held (a side that held every result commits at once; the other
waits out the deadline and commits on its own). After the heal each side re-plans from
its own epoch-0 plan and nothing would ever merge them. The rule, the same on every UAV
from the same two reports whatever the order they arrive in:

* the plan built from more results wins (its epoch-0 team is the larger: every report
  of a mission, at any epoch, carries the team its epoch-0 plan was computed for);
* of two teams of one size, the one that sorts first wins (a total order on facts both
  sides hold; a digest would not do, for a later epoch's digest is not its basis's).

A UAV whose plan loses re-bases onto the winner (`fleet.consensus.mission_round`,
`MissionRound.rebase`): it follows the winner's epochs, keeps the targets reached (an
arrival is a fact) and gives its fresh standing for the winner's next re-plan, which
then counts it in. A UAV the winner's plan was built without (`MissionRound.joinable`)
stands for that plan at once, and the UAVs holding its epoch 0 count it in as they
count in a UAV back from a loss (`MissionRound.rejoin`): a new epoch, solved again with
it taking part. A report of a losing plan changes nothing for a UAV on the winner.

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum

__all__ = ["Rank", "rank"]


class Rank(Enum):
    """How another plan's epoch-0 team ranks against the one a UAV's plan is built on."""

    SAME = "same"
    STRONGER = "stronger"
    WEAKER = "weaker"


def rank(theirs: Sequence[int], ours: Sequence[int]) -> Rank:
    """How the plan built for epoch-0 team `theirs` ranks against ours (`ours`)."""
    a, b = tuple(sorted(theirs)), tuple(sorted(ours))
    if a == b:
        return Rank.SAME
    if len(a) != len(b):
        return Rank.STRONGER if len(a) > len(b) else Rank.WEAKER
    return Rank.STRONGER if a < b else Rank.WEAKER
