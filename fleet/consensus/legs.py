"""Target-to-target flight times: closed form, from the mission alone.

A UAV's approach time to each target comes from its own model (its result); the time
from one target to the next does not depend on the aircraft's state, only on the two
targets, so every UAV computes it identically from the mission it was sent, and nothing
more needs publishing for a queue (docs/queues.md). The leg is the great-circle distance
flown at `LEG_SPEED_MPS`, plus `LEG_TURN_S` for the turn at the target the aircraft
passes over: a closed form, not the approach model, which is too slow for T x T legs
(200 targets: 39,800 legs).

With no-fly zones, a leg whose straight line crosses one is the shortest route around
them (fleet.geo.visibility.zone_map, the onboard's inflation, at `LEG_SPEED_MPS`): the
mission fixes the zones, so every UAV still computes the same legs. A leg no route flies
is infinite: the plan never queues it. Wind is left out: each UAV's estimate of it
differs, and the legs must not.

Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from fleet.geo import great_circle
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import zone_map
from fleet.mission.messages import NoFlyZone, Target
from fleet.mission.no_fly import local_zones

#: The airspeed (m/s) a leg is flown at: the simulated aircraft's cruise.
LEG_SPEED_MPS = 22.0
#: Seconds added to every leg for the turn over the target just reached: half a
#: standard-rate 360-degree turn (a 180-degree reversal at 3 deg/s takes 60 s; the mean
#: turn is about a quarter of that, rounded up).
LEG_TURN_S = 15.0


def great_circle_m(a: Target, b: Target) -> float:
    """Metres along the great circle between two targets (fleet.geo.great_circle)."""
    return great_circle.great_circle_m(a.lat, a.lon, b.lat, b.lon)


def leg_times(
    targets: Sequence[Target],
    speed_mps: float = LEG_SPEED_MPS,
    turn_s: float = LEG_TURN_S,
    zones: Sequence[NoFlyZone] = (),
) -> list[list[float]]:
    """`legs[i][j]`: seconds from target i to target j (0 on the diagonal), around
    `zones` where the straight line crosses one."""
    count = len(targets)
    legs = [[0.0] * count for _ in range(count)]
    around = _zone_routes(targets, zones, speed_mps) if zones and count else None
    for i in range(count):
        for j in range(i + 1, count):
            metres = great_circle_m(targets[i], targets[j])
            if around is not None:
                metres = around(i, j, metres)
            legs[i][j] = legs[j][i] = metres / speed_mps + turn_s
    return legs


def _zone_routes(
    targets: Sequence[Target], zones: Sequence[NoFlyZone], speed_mps: float
) -> Callable[[int, int, float], float]:
    """A leg's metres around the zones: the great circle where the line is clear, else
    the shortest route's length (inf where none), on a plane centred on the first target."""
    projection = MercatorProjection(targets[0].lat, targets[0].lon)
    around = zone_map(local_zones(projection, zones), AircraftLimits(), speed_mps)
    points = [projection.to_xy(t.lat, t.lon) for t in targets]

    def metres(i: int, j: int, straight: float) -> float:
        if around.clear(points[i], points[j]):
            return straight
        route = around.route(points[i], points[j])
        return math.inf if route is None else route.length

    return metres
