"""Loitering clear of the mission's no-fly zones, where an aircraft waits once its part
is done.

The module cannot see its autopilot's course (the flight plan is the operator's, and
its legs may cross the zones), so in a mission with zones it never sends the aircraft
back to it: after a target, the target waypoint's `next` is a loiter, and an aircraft
that gives its target up (released, failed, a new mission) loiters where it is. A loiter
is two waypoints, `LOITER_WAYPOINTS` (88 at the anchor, 89 at the far end), each one's
`next` the other: the autopilot shuttles between them by itself.

It is clear of the zones with its turns: the segment and both its ends keep
`2 * turn radius + ZONE_MARGIN_M` from every zone, for a U-turn at the bank limit sweeps
up to two turn radii to one side of the line. The anchor is the point itself (the target
just reached, the aircraft's position) when that is clear, else the nearest clear point
on rings around it that a straight leg out of the zones (as a route's) reaches.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import ZoneMap, zone_map
from fleet.geo.zones import ZONE_MARGIN_M, Point, Ring
from fleet.mission.messages import NoFlyZone
from fleet.mission.no_fly import local_zones
from fleet.piccolo.waypoint import Waypoint

#: The loiter's anchor and far end (the target route uses 90 and up).
LOITER_ANCHOR = 88
LOITER_FAR = 89
LOITER_WAYPOINTS = (LOITER_ANCHOR, LOITER_FAR)
#: The length of the loiter's leg (m): a few turn radii, so that it is not all turning.
LOITER_LENGTH_M = 800.0
#: Directions tried for the leg, and for an anchor moved off a point too near a zone.
_BEARINGS = 16
#: An anchor moved off the point goes out in rings this far apart (m), this many.
_ANCHOR_STEP_M = 250.0
_ANCHOR_RINGS = 8
_LIMITS = AircraftLimits()


def loiter_clearance(speed: float, limits: AircraftLimits = _LIMITS) -> float:
    """How far (m) a loiter keeps from every zone at `speed` (m/s)."""
    return 2.0 * limits.turn_radius(limits.clamp_airspeed(speed)) + ZONE_MARGIN_M


def plan_loiter(
    start: Point,
    heading: float,
    zones: Sequence[Ring],
    speed: float,
    limits: AircraftLimits = _LIMITS,
) -> tuple[Point, Point] | None:
    """The anchor and far end of a loiter clear of `zones` (local metres) near `start`,
    its leg as close to `heading` (radians from east, counter-clockwise) as is clear;
    None when none is found within the rings searched."""
    clear_of = ZoneMap(zones, loiter_clearance(speed, limits))
    routes = zone_map(zones, limits, speed)
    leaving = routes.containing(start)
    for anchor in _anchors(start, heading):
        if clear_of.containing(anchor):
            continue
        if anchor != start and not routes.clear(start, anchor, leaving):
            continue
        for direction in _directions(heading):
            far = (
                anchor[0] + LOITER_LENGTH_M * math.cos(direction),
                anchor[1] + LOITER_LENGTH_M * math.sin(direction),
            )
            if not clear_of.containing(far) and clear_of.clear(anchor, far):
                return anchor, far
    return None


def _directions(heading: float) -> Iterator[float]:
    """`heading`, then alternately either side of it, a step further each time."""
    step = 2.0 * math.pi / _BEARINGS
    yield heading
    for k in range(1, _BEARINGS // 2 + 1):
        yield heading + k * step
        if k < _BEARINGS // 2:
            yield heading - k * step


def _anchors(start: Point, heading: float) -> Iterator[Point]:
    yield start
    for ring in range(1, _ANCHOR_RINGS + 1):
        for direction in _directions(heading):
            yield (
                start[0] + ring * _ANCHOR_STEP_M * math.cos(direction),
                start[1] + ring * _ANCHOR_STEP_M * math.sin(direction),
            )


def loiter_writes(
    at: tuple[float, float],
    toward: tuple[float, float],
    alt: float,
    zones: Sequence[NoFlyZone],
    speed: float,
) -> list[Waypoint] | None:
    """The loiter's two waypoints, in the order to write them (the far end, which the
    anchor leads to, first), for a loiter at `at` (latitude, longitude) with its leg
    toward `toward`; None if no clear loiter is found near it."""
    projection = MercatorProjection(*at)
    tx, ty = projection.to_xy(*toward)
    heading = math.atan2(ty, tx) if (tx, ty) != (0.0, 0.0) else 0.0
    found = plan_loiter((0.0, 0.0), heading, local_zones(projection, zones), speed)
    if found is None:
        return None
    (ax, ay), (fx, fy) = found
    anchor, far = projection.to_latlon(ax, ay), projection.to_latlon(fx, fy)
    return [
        Waypoint(LOITER_FAR, LOITER_ANCHOR, far[0], far[1], alt),
        Waypoint(LOITER_ANCHOR, LOITER_FAR, anchor[0], anchor[1], alt),
    ]
