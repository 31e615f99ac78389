"""The autopilot's flight plan: waypoints 0-99 linked by `next`, pure.

A Piccolo tracks one waypoint at a time; on reaching it, it goes on to that waypoint's
`next` (thesis 1.4.1, docs/protocol.md §3). A flight plan is therefore just the table of
stored waypoints: a closed chain is what following `next` from a waypoint gives when it
comes back to where it started. The table accepts any waypoint with valid indices, even
one whose `next` is not (yet) stored, because a sender uploads a plan one waypoint at a
time and the chain is only closed once the last one arrives.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from fleet.errors import FleetError
from fleet.geo.mercator import MercatorProjection
from fleet.piccolo.waypoint import MAX_INDEX, Waypoint

#: Default racetrack: length along the initial heading and width to its right (m).
RACETRACK_LENGTH = 3000.0
RACETRACK_WIDTH = 1000.0


class FlightPlanError(FleetError, ValueError):
    """A waypoint index outside 0-99, or a plan that is not a closed chain."""


def check_indices(waypoint: Waypoint) -> None:
    """Raise FlightPlanError unless the waypoint's index and `next` are in 0-99."""
    for name, value in (("index", waypoint.index), ("next", waypoint.next_index)):
        if not 0 <= value <= MAX_INDEX:
            raise FlightPlanError(f"waypoint {name} {value} is outside 0-{MAX_INDEX}")


class FlightPlan:
    """The stored waypoints, by index."""

    def __init__(self, waypoints: Iterable[Waypoint] = ()) -> None:
        self._waypoints: dict[int, Waypoint] = {}
        for waypoint in waypoints:
            self.store(waypoint)

    def store(self, waypoint: Waypoint) -> None:
        """Create or replace waypoint `waypoint.index`."""
        check_indices(waypoint)
        self._waypoints[waypoint.index] = waypoint

    def get(self, index: int) -> Waypoint | None:
        return self._waypoints.get(index)

    def __contains__(self, index: object) -> bool:
        return index in self._waypoints

    def __len__(self) -> int:
        return len(self._waypoints)

    def waypoints(self) -> list[Waypoint]:
        """Every stored waypoint, by increasing index."""
        return [self._waypoints[index] for index in sorted(self._waypoints)]

    def chain(self, start: int) -> list[int]:
        """Indices met following `next` from `start`, each once, stopping at a repeat or
        at an index that is not stored. Empty if `start` is not stored."""
        indices: list[int] = []
        seen: set[int] = set()
        index = start
        # At most 100 distinct indices exist, so the walk is bounded.
        while index in self._waypoints and index not in seen:
            indices.append(index)
            seen.add(index)
            index = self._waypoints[index].next_index
        return indices

    def is_closed_chain(self, start: int) -> bool:
        """True if following `next` from `start` comes back to `start`."""
        indices = self.chain(start)
        return bool(indices) and self._waypoints[indices[-1]].next_index == start


def closed_chain(
    points: Sequence[tuple[float, float, float]], first_index: int = 0
) -> list[Waypoint]:
    """Waypoints `first_index`, `first_index + 1`, ... at (lat, lon, alt) `points`, each
    linked to the following one and the last back to the first."""
    if not points:
        raise FlightPlanError("a flight plan needs at least one waypoint")
    if first_index < 0 or first_index + len(points) - 1 > MAX_INDEX:
        raise FlightPlanError(
            f"{len(points)} waypoints from index {first_index} do not fit in 0-{MAX_INDEX}"
        )
    count = len(points)
    return [
        Waypoint(
            index=first_index + i,
            next_index=first_index + (i + 1) % count,
            lat=lat,
            lon=lon,
            alt=alt,
        )
        for i, (lat, lon, alt) in enumerate(points)
    ]


def racetrack(
    lat: float,
    lon: float,
    alt: float,
    heading_deg: float,
    *,
    length: float = RACETRACK_LENGTH,
    width: float = RACETRACK_WIDTH,
) -> list[tuple[float, float, float]]:
    """Corners (lat, lon, alt) of a racetrack ahead of a start point, in flying order.

    Corner 0 is `length` metres ahead along the heading, so an aircraft starting there
    and tracking it flies straight on; then `width` to the right, back abreast of the
    start, and the start itself, closing the loop.
    """
    projection = MercatorProjection(lat, lon)
    heading = math.radians(heading_deg)
    ahead = (math.sin(heading), math.cos(heading))
    right = (math.cos(heading), -math.sin(heading))
    corners = ((length, 0.0), (length, width), (0.0, width), (0.0, 0.0))
    points = []
    for along, across in corners:
        x = along * ahead[0] + across * right[0]
        y = along * ahead[1] + across * right[1]
        corner_lat, corner_lon = projection.to_latlon(x, y)
        points.append((corner_lat, corner_lon, alt))
    return points
