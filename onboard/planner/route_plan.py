"""Approach times around no-fly zones: the route fixes the geometry, the model the timing.

With no-fly zones, a target's time is the time of a route that stays out of every zone
inflated by the turn radius at the aircraft's airspeed plus `ZONE_MARGIN_M`
(fleet.geo.visibility.zone_map, the inflation the route is flown on too): the approach
from the aircraft's position and heading to the route's first point is the approach
model's (the LP, or its Dubins fallback, exactly as for a target in open air), and the
legs after it are straight legs at that speed (`leg_time`). Where the straight line is
clear, the route is the target alone and the time is the model's, as without zones. A
target no route reaches, or whose route turns more often than the autopilot has
waypoints for it (`MAX_ROUTE_TURNS`), gets an infinite time: published as None, so the
team leaves it `unserved` unless another UAV reaches it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.visibility import Route, legs_time, zone_map
from fleet.geo.wind import CALM_AIR, Wind, airspeed
from fleet.geo.zones import Point, Ring

__all__ = ["MAX_ROUTE_TURNS", "RoutedTargets", "route_targets"]

#: Turns a route may have: one autopilot waypoint each (onboard.route_flight).
MAX_ROUTE_TURNS = 9


@dataclass(frozen=True)
class RoutedTargets:
    """Per target: the point the approach model is asked for (the route's first), the
    time of the legs after it, and the route (None: unreachable)."""

    aims: tuple[Point, ...]
    rest_s: tuple[float, ...]
    routes: tuple[Route | None, ...]

    def time(self, index: int, approach_s: float) -> float:
        """The whole route's time, given the approach model's time to its first point."""
        return approach_s + self.rest_s[index]


def route_targets(
    position: Point,
    velocity: Point,
    targets: Sequence[Point],
    zones: Sequence[Ring],
    limits: AircraftLimits,
    wind: Wind = CALM_AIR,
    speed: float | None = None,
) -> RoutedTargets:
    """Routes from `position` to every target around `zones` (local metres); the legs
    after the first point timed in `wind` (still air by default). `velocity` is over the
    ground; `speed` is the airspeed held (the request's: `LinkWatch.airspeed`, the one
    the route is flown at), else what the wind does not account for of `velocity`."""
    speed = limits.clamp_airspeed(airspeed(velocity, wind) if speed is None else speed)
    zone_routes = zone_map(zones, limits, speed)
    aims: list[Point] = []
    rest: list[float] = []
    routes: list[Route | None] = []
    for target in targets:
        route = zone_routes.route(position, target)
        if route is None or len(route.points) - 1 > MAX_ROUTE_TURNS:
            aims.append(target)
            rest.append(math.inf)
            routes.append(None)
            continue
        aims.append(route.points[0])
        rest.append(legs_time(route.points, speed, wind))
        routes.append(route)
    return RoutedTargets(tuple(aims), tuple(rest), tuple(routes))
