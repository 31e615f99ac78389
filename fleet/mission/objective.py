"""What a mission's plan optimises: the ground chooses, every UAV applies it.

Pure: no I/O.
"""

from __future__ import annotations

from enum import StrEnum


class Objective(StrEnum):
    """The plan's objective. Values are the strings on the bus and the command line."""

    #: The thesis's greedy (section 4.4.3), extended to queues by earliest finishing time.
    GREEDY = "greedy"
    #: The least total of the targets' arrival times.
    MIN_SUM = "min-sum"
    #: The earliest time at which the last target is reached.
    MIN_MAX = "min-max"
