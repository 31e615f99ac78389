"""The point-mass LP's shape, shared by the LP the onboard runs (`onboard.planner.approach_highs`)
and its Pyomo reference (`onboard.planner.approach_pyomo`): the 16-gons, how a column is named
and changed, and what the LP scan (`onboard.planner.approach_model`) asks of either; and the
16-gon gauge the scan proves its bounds with.

Wind: the LP plans in the air mass. Its positions are the aircraft's in the air, and the
target, fixed on the ground, drifts through the air at minus the wind: at node k it is at
target - wind * t_k. The wind enters as two columns (`wx`, `wy`, fixed through their
bounds like the target) with coefficient t_k in the rows that select node k, so a
change of wind is again a change of bounds only.
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
    "gauge",
    "grid_times",
    "reach_time",
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


def grid_times(steps: Sequence[float]) -> tuple[float, ...]:
    """The time of every node (s): 0, then the running sum of `steps`, in this order, so
    that both LPs get bit-identical coefficients."""
    times = [0.0]
    for dt in steps:
        times.append(times[-1] + dt)
    return tuple(times)


def gauge(vector: tuple[float, float]) -> float:
    """The 16-gon gauge max(n . v) over the facet normals: |v| to within 2 %, and >= 0."""
    return max(nx * vector[0] + ny * vector[1] for nx, ny in NORMALS)


def reach_time(offset: tuple[float, float], wind: tuple[float, float], v_cap: float) -> float:
    """The first time (s) a point mass whose air velocity stays in the speed 16-gon
    (inradius `v_cap`) can be on a ground point `offset` away, in `wind`: a lower bound
    on any approach time, exact in closed form for the 16-gon.

    Seen from the air the point is at offset - wind t, inside the 16-gon of radius
    v_cap t when n . offset <= (v_cap + n . wind) t on every facet n. The wind must be
    slower than `v_cap` (every facet then has a positive rate).
    """
    worst = 0.0
    for nx, ny in NORMALS:
        reach = nx * offset[0] + ny * offset[1]
        if reach > 0.0:
            worst = max(worst, reach / (v_cap + nx * wind[0] + ny * wind[1]))
    return worst
