"""The point-mass LP's shape, shared by the LP the onboard runs (`onboard.approach_highs`)
and its Pyomo reference (`onboard.approach_pyomo`): the 16-gons, how a column is named
and changed, and what the LP scan (`onboard.approach_model`) asks of either.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

from fleet.errors import FleetError

__all__ = [
    "ACCEL_INRADIUS",
    "NORMALS",
    "SIDES",
    "SPEED_INRADIUS",
    "ApproachModelError",
    "BoundChange",
    "Column",
    "LinearProgram",
]

SIDES = 16
_HALF_SIDE = math.pi / SIDES
#: Inradius of the acceleration 16-gon, inscribed in the unit circle.
ACCEL_INRADIUS = math.cos(_HALF_SIDE)
#: Inradius of the speed 16-gon scaled to a mean radius of 1: the inscribed 16-gon's mean
#: radius is cos(h) ln(sec h + tan h) / h with h = pi/16, so this is h / ln(sec h + tan h).
SPEED_INRADIUS = _HALF_SIDE / math.log(1.0 / math.cos(_HALF_SIDE) + math.tan(_HALF_SIDE))
#: Facet normals of a 16-gon with a vertex at angle 0 (dead ahead in the heading frame).
NORMALS = tuple(
    (math.cos((2 * i + 1) * math.pi / SIDES), math.sin((2 * i + 1) * math.pi / SIDES))
    for i in range(SIDES)
)


class ApproachModelError(FleetError, RuntimeError):
    """The model could not be built or handed to the solver."""


#: A variable of the LP: its name in the Pyomo model and its index (0 for a scalar).
Column = tuple[str, int]
#: New lower and upper bounds of a variable; None is unbounded.
BoundChange = tuple[Column, float | None, float | None]


class LinearProgram(Protocol):
    """The point-mass LP, changed through variable bounds only."""

    def set_bounds(self, changes: Sequence[BoundChange]) -> None: ...

    def minimise(self) -> float | None:
        """The optimal objective, or None if HiGHS found no optimum."""
        ...
