"""No-fly zones as polygons on the local plane: validation, containment, inflation.

A zone arrives as a ring of WGS-84 (latitude, longitude) vertices and is taken to the
local metric plane of a `MercatorProjection` (`ring_to_local`) before any geometry: on
that plane, a kilometre-scale polygon's edges are straight to well under a metre.

A zone is checked once (`validate_ring`): enough vertices and not too many, every
vertex finite, no repeated vertex, no edge crossing another (a self-intersecting ring
has no inside anyone agrees on) and a non-zero area. A closing vertex equal to the
first (GeoJSON's convention) is dropped.

Aircraft do not fly polygons' edges: an aircraft that turns at a vertex swings out by
up to its turn radius, and its position is known only to a few metres. So routes keep
out of each zone **inflated** (`inflate`) by the turn radius plus a margin. Inflation
works on the zone's convex hull: the hull's outward offset is a convex polygon with
tangent segments standing for the rounded corners, so it contains every point within
the distance of the zone (it never cuts a corner), and shortest routes around convex
obstacles go from hull vertex to hull vertex (fleet.geo.visibility). A concave zone's
bay is therefore never entered, even where an aircraft would fit: the price of
guarantees that hold for every shape.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

from fleet.errors import FleetError
from fleet.geo.mercator import MercatorProjection

__all__ = [
    "MAX_ZONE_VERTICES",
    "MIN_ZONE_VERTICES",
    "ZONE_MARGIN_M",
    "Point",
    "Ring",
    "ZoneError",
    "convex_hull",
    "distance_to_segment",
    "inflate",
    "point_in_ring",
    "ring_to_local",
    "segment_enters",
    "validate_ring",
]

Point = tuple[float, float]
Ring = tuple[Point, ...]

#: A triangle is the smallest area-enclosing ring.
MIN_ZONE_VERTICES = 3
#: Vertices per zone at most: enough for a town's outline, bounded so that a hostile
#: mission cannot make every aircraft's route search quadratic in a huge polygon.
MAX_ZONE_VERTICES = 64
#: Below this area (m^2) a ring encloses nothing an aircraft could keep out of.
MIN_ZONE_AREA_M2 = 1.0
#: Arcs of the rounded corners are replaced by tangent segments of at most this angle:
#: 45 degrees puts the segments' corners at most 8 % of the distance beyond the arc.
_CORNER_STEP_RAD = math.pi / 4.0
#: Geometry tolerance (m): well under the projection's and the GPS's errors.
EPSILON_M = 1e-6
#: Beyond the turn radius, how far a route keeps from a zone (m): GPS error, the
#: autopilot's corner cutting within its acceptance radius, a gust.
ZONE_MARGIN_M = 40.0


class ZoneError(FleetError, ValueError):
    """A ring that is not a usable zone; the message says which vertex or edge, and why."""


def ring_to_local(projection: MercatorProjection, ring: Sequence[tuple[float, float]]) -> Ring:
    """A ring of (latitude, longitude) degrees on `projection`'s plane (x east, y north)."""
    return tuple(projection.to_xy(lat, lon) for lat, lon in ring)


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def signed_area(ring: Sequence[Point]) -> float:
    """Shoelace area: positive when the ring runs counter-clockwise."""
    total = 0.0
    for i, (x0, y0) in enumerate(ring):
        x1, y1 = ring[(i + 1) % len(ring)]
        total += x0 * y1 - x1 * y0
    return total / 2.0


def _segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool:
    """Segments ab and cd share a point (touching counts)."""
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return any(
        side == 0.0 and _on_segment(p, q, r)
        for side, p, q, r in ((d1, c, d, a), (d2, c, d, b), (d3, a, b, c), (d4, a, b, d))
    )


def _on_segment(p: Point, q: Point, r: Point) -> bool:
    """r, collinear with pq, lies on the segment pq."""
    return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and min(p[1], q[1]) <= r[1] <= max(p[1], q[1])


def validate_ring(ring: Sequence[Point], what: str = "zone") -> Ring:
    """`ring` as a usable zone (closing vertex dropped, counter-clockwise); else ZoneError."""
    points = [(float(x), float(y)) for x, y in ring]
    if len(points) > 1 and points[0] == points[-1]:
        points.pop()
    if len(points) < MIN_ZONE_VERTICES:
        raise ZoneError(f"{what}: {len(points)} vertices, expected at least {MIN_ZONE_VERTICES}")
    if len(points) > MAX_ZONE_VERTICES:
        raise ZoneError(
            f"{what}: {len(points)} vertices, more than the {MAX_ZONE_VERTICES} allowed"
        )
    for i, (x, y) in enumerate(points):
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ZoneError(f"{what}: vertex {i} is not finite")
    if len(set(points)) != len(points):
        raise ZoneError(f"{what}: a vertex is repeated (the ring touches itself)")
    n = len(points)
    for i in range(n):
        a, b = points[i], points[(i + 1) % n]
        # Adjacent edges share a vertex by construction: only the others may not meet.
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            if _segments_cross(a, b, points[j], points[(j + 1) % n]):
                raise ZoneError(f"{what}: edges {i} and {j} cross (the ring intersects itself)")
    area = signed_area(points)
    if abs(area) < MIN_ZONE_AREA_M2:
        raise ZoneError(f"{what}: it encloses no area")
    return tuple(points) if area > 0 else tuple(reversed(points))


def point_in_ring(point: Point, ring: Sequence[Point]) -> bool:
    """`point` is inside `ring` or on its boundary (even-odd rule)."""
    x, y = point
    inside = False
    n = len(ring)
    for i in range(n):
        (x0, y0), (x1, y1) = ring[i], ring[(i + 1) % n]
        if distance_to_segment(point, (x0, y0), (x1, y1)) <= EPSILON_M:
            return True
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def distance_to_segment(p: Point, a: Point, b: Point) -> float:
    """Metres from `p` to the segment `a`-`b` (local plane)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2
    t = min(1.0, max(0.0, t))
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def strictly_inside(point: Point, ring: Sequence[Point]) -> bool:
    """`point` is inside `ring`, farther than the tolerance from its boundary."""
    if not point_in_ring(point, ring):
        return False
    n = len(ring)
    return all(distance_to_segment(point, ring[i], ring[(i + 1) % n]) > EPSILON_M for i in range(n))


def segment_enters(a: Point, b: Point, ring: Sequence[Point]) -> bool:
    """The segment ab passes through `ring`'s interior (running along an edge or
    touching a vertex does not count)."""
    # The ring's edges cut ab into pieces, each wholly inside or outside: ab enters
    # exactly when some piece's midpoint is strictly inside.
    dx, dy = b[0] - a[0], b[1] - a[1]
    cuts = [0.0, 1.0]
    n = len(ring)
    for i in range(n):
        c, d = ring[i], ring[(i + 1) % n]
        ex, ey = d[0] - c[0], d[1] - c[1]
        denominator = dx * ey - dy * ex
        if denominator == 0.0:
            continue  # parallel: its endpoints below cut ab where they touch it
        t = ((c[0] - a[0]) * ey - (c[1] - a[1]) * ex) / denominator
        u = ((c[0] - a[0]) * dy - (c[1] - a[1]) * dx) / denominator
        if 0.0 < t < 1.0 and -1e-12 <= u <= 1.0 + 1e-12:
            cuts.append(t)
    length2 = dx * dx + dy * dy
    if length2 > 0.0:
        for v in ring:
            t = ((v[0] - a[0]) * dx + (v[1] - a[1]) * dy) / length2
            if 0.0 < t < 1.0:
                cuts.append(t)
    cuts.sort()
    for t0, t1 in itertools.pairwise(cuts):
        if t1 - t0 <= 1e-12:
            continue
        mid = (t0 + t1) / 2.0
        if strictly_inside((a[0] + mid * dx, a[1] + mid * dy), ring):
            return True
    return False


def convex_hull(points: Sequence[Point]) -> Ring:
    """The convex hull, counter-clockwise, collinear points dropped (Andrew's chain)."""
    ordered = sorted(set(points))
    if len(ordered) < 3:
        return tuple(ordered)

    def chain(sequence: Sequence[Point]) -> list[Point]:
        hull: list[Point] = []
        for p in sequence:
            while len(hull) >= 2 and _cross(hull[-2], hull[-1], p) <= 0.0:
                hull.pop()
            hull.append(p)
        return hull

    lower, upper = chain(ordered), chain(ordered[::-1])
    return tuple(lower[:-1] + upper[:-1])


def inflate(ring: Sequence[Point], distance: float) -> Ring:
    """A convex ring containing every point within `distance` (m) of `ring`.

    The hull's edges pushed out by `distance`, each corner's arc replaced by segments
    tangent to it (so the result circumscribes the rounded offset, never cuts it).
    """
    if not (math.isfinite(distance) and distance >= 0.0):
        raise ValueError(f"inflation must be a finite distance >= 0, got {distance}")
    hull = convex_hull(ring)
    if distance == 0.0 or len(hull) < 3:
        return hull
    n = len(hull)
    out: list[Point] = []
    for i, (x, y) in enumerate(hull):
        before, after = hull[i - 1], hull[(i + 1) % n]
        # Outward normals of the edge arriving at and the edge leaving this vertex
        # (counter-clockwise ring: the outside is on the right).
        start = math.atan2(-(x - before[0]), y - before[1])
        turn = (math.atan2(-(after[0] - x), after[1] - y) - start) % math.tau
        steps = max(1, math.ceil(turn / _CORNER_STEP_RAD - 1e-9))
        step = turn / steps
        reach = distance / math.cos(step / 2.0)
        for k in range(steps):
            angle = start + (k + 0.5) * step
            out.append((x + reach * math.cos(angle), y + reach * math.sin(angle)))
    return tuple(out)
