"""Flying a target around no-fly zones: the route as a chain of autopilot waypoints.

The route is planned again when the target is written, from the aircraft's position
then, on the zones inflated exactly as for the approach time
(fleet.geo.visibility.zone_map at the airspeed held, `LinkWatch.airspeed`,
onboard.planner.route_plan), so the route flown is the one timed, from where the aircraft now
is. Its turns become waypoints `ROUTE_WAYPOINTS` (91, 92, ...), each one's `next` the
following turn and the last turn's the target waypoint (90), whose `next` is the course
to come back to, as without zones. The waypoints are written from the target back to the
first turn, each only once the autopilot echoed the one before, so the autopilot never
holds a chain leading to a waypoint it does not have; then the track to the first turn.
The autopilot sequences the turns by itself (it moves on at each one's acceptance
radius), so the module's arrival and departure logic is the target's as before.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import zone_map
from fleet.mission.messages import NoFlyZone, Target
from fleet.mission.no_fly import local_zones
from fleet.piccolo.telemetry import GpsBlock
from fleet.piccolo.waypoint import Waypoint
from onboard.planner.route_plan import MAX_ROUTE_TURNS

log = logging.getLogger(__name__)

#: The waypoint indices a route's turns are written into, in order.
ROUTE_WAYPOINTS = tuple(range(91, 91 + MAX_ROUTE_TURNS))
_LIMITS = AircraftLimits()


def route_turns(
    gps: GpsBlock, target: Target, zones: Sequence[NoFlyZone], speed: float
) -> tuple[tuple[float, float], ...] | None:
    """The (latitude, longitude) of each turn of the route from `gps` to `target` around
    `zones`, inflated at the airspeed `speed` (`LinkWatch.airspeed`, the one the approach
    time was planned at): () for the straight line; None when no route reaches it now."""
    if not zones:
        return ()
    projection = MercatorProjection(gps.lat, gps.lon)
    route = zone_map(local_zones(projection, zones), _LIMITS, speed).route(
        (0.0, 0.0), projection.to_xy(target.lat, target.lon)
    )
    if route is None or len(route.points) - 1 > len(ROUTE_WAYPOINTS):
        return None
    return tuple(projection.to_latlon(x, y) for x, y in route.points[:-1])


def route_writes(
    target_index: int, target: Target, turns: Sequence[tuple[float, float]], back_to: int
) -> tuple[list[Waypoint], int]:
    """The waypoints to write, in the order to write them (the target first), and the
    waypoint to track: the first turn, or the target itself with no turn."""
    writes = [Waypoint(target_index, back_to, target.lat, target.lon, target.alt)]
    following = target_index
    for index, (lat, lon) in reversed(list(zip(ROUTE_WAYPOINTS, turns, strict=False))):
        writes.append(Waypoint(index, following, lat, lon, target.alt))
        following = index
    return writes, following
