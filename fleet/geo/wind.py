"""Straight flight in a steady wind: ground speed along a leg and the time to fly it.

An aircraft holding a ground track in a crosswind crabs into it: its air-relative
velocity (of magnitude the airspeed V) points upwind of the track so that the wind's
cross-track component is cancelled, and what is left of the airspeed, plus the wind's
along-track component, is its ground speed

    ground speed = sqrt(V^2 - w_cross^2) + w_along.

A leg the aircraft cannot make good (a crosswind at least as fast as the aircraft, or a
headwind that leaves no ground speed) takes forever: `math.inf`, never an exception, so
a planner that times route legs with it simply never chooses such a leg.

Frames follow the rest of `fleet.geo`: local metres with x east and y north. A wind is
the velocity of the air mass over the ground, the way it blows *to* (a "westerly", from
the west, has a positive `east`). A Piccolo reports it as `wind_south` and `wind_west`
(the components toward south and west): `Wind.from_piccolo` turns those round.
Bearings are degrees clockwise from true north, the operator's unit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

__all__ = [
    "CALM_AIR",
    "Wind",
    "air_velocity",
    "airspeed",
    "ground_speed_along",
    "leg_time",
    "straight_leg_time",
]

# Below this ground speed (m/s) a leg counts as not flyable: a near-zero ground speed
# would give times of days, which no planner can use either.
_MIN_GROUND_SPEED = 1e-6


class Wind(NamedTuple):
    """A steady wind: the air mass's velocity over the ground, m/s."""

    east: float = 0.0
    north: float = 0.0

    @classmethod
    def from_piccolo(cls, wind_south: float, wind_west: float) -> Wind:
        """The wind of a Piccolo's telemetry (its components toward south and west)."""
        return cls(east=-wind_west, north=-wind_south)

    @property
    def speed(self) -> float:
        return math.hypot(self.east, self.north)

    def at_most(self, speed: float) -> Wind:
        """This wind, scaled down to `speed` m/s if it is faster (its direction kept)."""
        current = self.speed
        if current <= speed:
            return self
        scale = speed / current
        return Wind(self.east * scale, self.north * scale)

    def __bool__(self) -> bool:
        # A NamedTuple of two zeros is truthy; "is there any wind" reads better.
        return self.east != 0.0 or self.north != 0.0


CALM_AIR = Wind()


def air_velocity(ground_velocity: tuple[float, float], wind: Wind) -> tuple[float, float]:
    """The velocity through the air (m/s, east and north) of an aircraft moving at
    `ground_velocity` over the ground in `wind`: what it turns and holds its speed in."""
    return (ground_velocity[0] - wind.east, ground_velocity[1] - wind.north)


def airspeed(ground_velocity: tuple[float, float], wind: Wind) -> float:
    """The airspeed (m/s) of an aircraft moving at `ground_velocity` in `wind`: what a
    GPS velocity says once the wind is taken out. Every planner and every flight takes
    it from here, with the one wind the aircraft plans with, so a time and the route
    flown for it agree on the speed."""
    return math.hypot(*air_velocity(ground_velocity, wind))


def ground_speed_along(direction: tuple[float, float], airspeed: float, wind: Wind) -> float:
    """Ground speed (m/s) of an aircraft at `airspeed` holding a track along `direction`.

    `direction` is any non-zero vector (x east, y north); the result is 0.0 where the
    track cannot be made good (see the module docstring).
    """
    length = math.hypot(direction[0], direction[1])
    if not length > 0.0:
        raise ValueError("a track direction must be a non-zero vector")
    ux, uy = direction[0] / length, direction[1] / length
    along = wind.east * ux + wind.north * uy
    cross = wind.north * ux - wind.east * uy
    still = airspeed * airspeed - cross * cross
    if still < 0.0:
        return 0.0
    return max(math.sqrt(still) + along, 0.0)


def leg_time(
    start: tuple[float, float], end: tuple[float, float], airspeed: float, wind: Wind
) -> float:
    """Seconds to fly straight from `start` to `end` (local metres) at `airspeed` in `wind`.

    0.0 for a leg of no length; `math.inf` for a leg the aircraft cannot make good.
    """
    dx = end[0] - start[0]
    dy = end[1] - start[1]
    distance = math.hypot(dx, dy)
    if distance == 0.0:
        return 0.0
    speed = ground_speed_along((dx, dy), airspeed, wind)
    return distance / speed if speed > _MIN_GROUND_SPEED else math.inf


def straight_leg_time(bearing_deg: float, distance: float, airspeed: float, wind: Wind) -> float:
    """Seconds to fly `distance` metres on a track of `bearing_deg` (clockwise from
    north) at `airspeed` in `wind`; `math.inf` for a leg that cannot be made good."""
    if distance < 0.0:
        raise ValueError(f"a leg's length must be >= 0, got {distance}")
    bearing = math.radians(bearing_deg)
    return leg_time(
        (0.0, 0.0), (distance * math.sin(bearing), distance * math.cos(bearing)), airspeed, wind
    )
