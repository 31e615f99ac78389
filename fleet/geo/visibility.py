"""The shortest route around no-fly zones, and its time: a visibility graph.

The zones, already inflated (fleet.geo.zones.inflate: convex), are the obstacles. The
shortest path between two points that keeps out of convex obstacles runs straight
between points and obstacle vertices that see each other, so the route is Dijkstra's
over the graph of those mutual sightlines (Lozano-Perez and Wesley, 1979). The sightlines
between zone vertices do not depend on the start or the goal: `ZoneMap` computes them
once per mission, and a route asks only the start's and the goal's (a few milliseconds
for three zones of eight vertices).

A start or goal inside an inflated zone (an aircraft near an edge, a target close to a
zone) leaves or enters that zone's inflation by the straight line, or via its inflated
vertices: its first or last leg keeps out of the zone itself, not of its inflation. An
aircraft already inside a zone is not stranded there: its first leg leaves the zone's
inflation by the shortest way (the nearest point of its boundary, `exit_point`), and
the route goes on from there. A goal no route reaches gets None.

The time of a route is its legs' times (`fleet.geo.wind.leg_time`: a straight leg at a
constant airspeed in a constant wind, still air by default); the approach to the route's first
point is the approach model's (onboard.planner.route_plan).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.wind import CALM_AIR, Wind, leg_time
from fleet.geo.zones import EPSILON_M, ZONE_MARGIN_M, Point, Ring, convex_hull, inflate

__all__ = ["Route", "ZoneMap", "legs_time", "zone_clearance", "zone_map"]


def zone_clearance(limits: AircraftLimits, airspeed: float) -> float:
    """How far (m) a route keeps from every zone: the turn radius at `airspeed` (clamped
    into the aircraft's envelope) plus `ZONE_MARGIN_M`."""
    return limits.turn_radius(limits.clamp_airspeed(airspeed)) + ZONE_MARGIN_M


def zone_map(zones: Sequence[Ring], limits: AircraftLimits, airspeed: float) -> ZoneMap:
    """The zones (local metres) inflated for an aircraft flying at `airspeed` (m/s):
    the one inflation every route is planned, timed and flown on."""
    return ZoneMap(zones, zone_clearance(limits, airspeed))


def legs_time(points: Sequence[Point], airspeed: float, wind: Wind = CALM_AIR) -> float:
    """Seconds along the polyline `points` (each leg by `fleet.geo.wind.leg_time`)."""
    return sum(leg_time(a, b, airspeed, wind) for a, b in itertools.pairwise(points))


@dataclass(frozen=True)
class Route:
    """Straight legs from a start through `points` (the last one is the goal)."""

    start: Point
    points: tuple[Point, ...]

    @property
    def length(self) -> float:
        return sum(
            math.dist(a, b) for a, b in zip((self.start, *self.points), self.points, strict=False)
        )

    @property
    def detours(self) -> bool:
        """The route turns at a zone's vertex (it is not the straight line)."""
        return len(self.points) > 1


class ZoneMap:
    """Zones inflated by `distance` (m) and the sightlines between their vertices."""

    def __init__(self, zones: Sequence[Ring], distance: float) -> None:
        #: Each zone's convex hull: what a leg out of (or into) its inflation avoids.
        self.cores: tuple[Ring, ...] = tuple(convex_hull(zone) for zone in zones)
        self.zones: tuple[Ring, ...] = tuple(inflate(zone, distance) for zone in self.cores)
        self._boxes = [_box(zone) for zone in self.zones]
        self._edges_of = [_edges(zone) for zone in self.zones]
        self._core_edges = [_edges(core) for core in self.cores]
        vertices: list[Point] = []
        #: Each vertex's two neighbours on its zone: a route turning there is tangent to it.
        self._sides: list[tuple[Point, Point]] = []
        self._zone_of: list[int] = []
        for i, zone in enumerate(self.zones):
            for k, v in enumerate(zone):
                # A vertex inside another zone's inflation can never be on a route.
                if not any(j != i and self._strictly_in(v, j) for j in range(len(self.zones))):
                    vertices.append(v)
                    self._sides.append((zone[k - 1], zone[(k + 1) % len(zone)]))
                    self._zone_of.append(i)
        self.vertices: tuple[Point, ...] = tuple(vertices)
        n = len(self.vertices)
        self._edges: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        for i in range(n):
            for j in range(i + 1, n):
                a, b = self.vertices[i], self.vertices[j]
                # Shortest routes between convex zones turn only where the line is
                # tangent at both ends (cheap): only those lines are checked in full.
                if self._tangent(i, b) and self._tangent(j, a) and self.clear(a, b):
                    d = math.dist(a, b)
                    self._edges[i].append((j, d))
                    self._edges[j].append((i, d))

    def _tangent(self, index: int, other: Point) -> bool:
        """The line from vertex `index` to `other` leaves both its neighbours on one side."""
        (ux, uy), (before, after) = self.vertices[index], self._sides[index]
        wx, wy = other[0] - ux, other[1] - uy
        first = wx * (before[1] - uy) - wy * (before[0] - ux)
        second = wx * (after[1] - uy) - wy * (after[0] - ux)
        slack = EPSILON_M * math.hypot(wx, wy) * 1e3
        return not ((first > slack and second < -slack) or (first < -slack and second > slack))

    def _sightline(
        self, index: int, end: Point, near: frozenset[int], within: int | None = None
    ) -> bool:
        """A route's first or last leg may join vertex `index` and `end`: tangent there
        (unless `end` is inside that vertex's zone's inflation: no line from inside is),
        and clear."""
        if self._zone_of[index] not in near and not self._tangent(index, end):
            return False
        return self.clear(self.vertices[index], end, near, within)

    def _strictly_in(self, point: Point, index: int) -> bool:
        return _inside_box(point, self._boxes[index]) and _inside_convex(
            point, self._edges_of[index]
        )

    def clear(
        self, a: Point, b: Point, near: frozenset[int] = frozenset(), within: int | None = None
    ) -> bool:
        """The segment ab enters no inflated zone; of the zones indexed in `near` (those
        an end of it is inside the inflation of), only the zone itself; and the zone
        indexed `within` (the one `a` is inside of) not at all."""
        box = _box((a, b))
        for index in range(len(self.zones)):
            if index == within or not _overlap(box, self._boxes[index]):
                continue
            edges = self._core_edges[index] if index in near else self._edges_of[index]
            if _enters_convex(a, b, edges):
                return False
        return True

    def containing(self, point: Point) -> frozenset[int]:
        """The zones `point` is strictly inside of."""
        return frozenset(i for i in range(len(self.zones)) if self._strictly_in(point, i))

    def route(self, start: Point, goal: Point) -> Route | None:
        """The shortest route from `start` to `goal` out of every zone; None if none."""
        leave, enter = self.containing(start), self.containing(goal)
        # Already inside a zone (blown in, or sent a mission there): its first leg leaves
        # it by the shortest way, then the route goes on from there.
        within = next((i for i in leave if _inside_convex(start, self._core_edges[i])), None)
        if within is not None:
            exit_at = self.exit_point(start, within)
            onward = self._route(exit_at, goal, self.containing(exit_at), enter, None)
            return None if onward is None else Route(start, (exit_at, *onward.points))
        return self._route(start, goal, leave, enter, within)

    def exit_point(self, point: Point, index: int) -> Point:
        """The nearest point out of zone `index`'s inflation from `point` inside it (a
        metre beyond its boundary, so that the route on from there starts outside)."""
        ring = self.zones[index]
        best, best_d = point, math.inf
        for a, b in zip(ring, (*ring[1:], ring[0]), strict=True):
            near = _closest_on_segment(point, a, b)
            d = math.dist(point, near)
            if d < best_d:
                best, best_d = near, d
        # Outwards: along the edge's normal (the ring is counter-clockwise).
        for a, b in zip(ring, (*ring[1:], ring[0]), strict=True):
            if math.dist(_closest_on_segment(point, a, b), best) <= EPSILON_M:
                length = math.dist(a, b)
                if length > 0.0:
                    return (
                        best[0] + (b[1] - a[1]) / length * _EXIT_BEYOND_M,
                        best[1] - (b[0] - a[0]) / length * _EXIT_BEYOND_M,
                    )
        return best

    def _route(
        self,
        start: Point,
        goal: Point,
        leave: frozenset[int],
        enter: frozenset[int],
        within: int | None,
    ) -> Route | None:
        if self.clear(start, goal, leave | enter, within):
            return Route(start, (goal,))
        n = len(self.vertices)
        # Nodes: the vertices 0..n-1, the start n, the goal n+1.
        distance = [math.inf] * (n + 2)
        previous = [-1] * (n + 2)
        distance[n] = 0.0
        to_goal = [
            math.dist(v, goal)
            if self._tangent(i, goal) and self.clear(v, goal, enter)
            else math.inf
            for i, v in enumerate(self.vertices)
        ]
        queue: list[tuple[float, int]] = [(0.0, n)]
        while queue:
            d, node = heapq.heappop(queue)
            if d > distance[node]:
                continue
            if node == n + 1:
                break
            if node == n:
                out = [
                    (j, math.dist(start, v))
                    for j, v in enumerate(self.vertices)
                    if self._sightline(j, start, leave, within)
                ]
            else:
                out = list(self._edges[node])
                if math.isfinite(to_goal[node]):
                    out.append((n + 1, to_goal[node]))
            for j, step in out:
                if d + step < distance[j]:
                    distance[j] = d + step
                    previous[j] = node
                    heapq.heappush(queue, (d + step, j))
        if not math.isfinite(distance[n + 1]):
            return None
        points = [goal]
        node = previous[n + 1]
        while node != n:
            points.append(self.vertices[node])
            node = previous[node]
        return Route(start, tuple(reversed(points)))


_Box = tuple[float, float, float, float]
#: How far beyond a zone's inflation the shortest way out of it ends (m).
_EXIT_BEYOND_M = 1.0


def _closest_on_segment(p: Point, a: Point, b: Point) -> Point:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    if length2 == 0.0:
        return a
    t = max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2))
    return (a[0] + t * dx, a[1] + t * dy)


#: A convex ring's edges, each its start and unit direction (x0, y0, ux, uy).
_Edges = list[tuple[float, float, float, float]]


def _edges(ring: Ring) -> _Edges:
    edges = []
    for i, (x0, y0) in enumerate(ring):
        x1, y1 = ring[(i + 1) % len(ring)]
        length = math.hypot(x1 - x0, y1 - y0)
        if length > 0.0:
            edges.append((x0, y0, (x1 - x0) / length, (y1 - y0) / length))
    return edges


def _inside_convex(point: Point, edges: _Edges) -> bool:
    """`point` is inside the counter-clockwise convex ring, beyond the tolerance."""
    return all(ux * (point[1] - y0) - uy * (point[0] - x0) > EPSILON_M for x0, y0, ux, uy in edges)


def _enters_convex(a: Point, b: Point, edges: _Edges) -> bool:
    """The segment ab passes through the interior of a counter-clockwise convex ring
    (running along an edge or touching a vertex does not count): Cyrus-Beck clipping."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    low, high = 0.0, 1.0
    for x0, y0, ux, uy in edges:
        # Distance inside this edge's line, along the segment: start + t * rate.
        start = ux * (a[1] - y0) - uy * (a[0] - x0) - EPSILON_M
        rate = ux * dy - uy * dx
        if rate == 0.0:
            if start <= 0.0:
                return False
            continue
        t = -start / rate
        if rate > 0.0:
            low = max(low, t)
        else:
            high = min(high, t)
        if low >= high:
            return False
    return (high - low) * math.hypot(dx, dy) > EPSILON_M


def _box(points: Sequence[Point]) -> _Box:
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    return min(xs), min(ys), max(xs), max(ys)


def _overlap(a: _Box, b: _Box) -> bool:
    return a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3]


def _inside_box(p: Point, box: _Box) -> bool:
    return box[0] <= p[0] <= box[2] and box[1] <= p[1] <= box[3]
