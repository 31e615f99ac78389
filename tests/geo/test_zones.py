"""Tests of no-fly zone geometry (fleet.geo.zones) and routes around zones
(fleet.geo.visibility)."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import ZoneMap, legs_time, zone_clearance, zone_map
from fleet.geo.wind import Wind
from fleet.geo.zones import (
    MAX_ZONE_VERTICES,
    ZONE_MARGIN_M,
    ZoneError,
    convex_hull,
    inflate,
    point_in_ring,
    ring_to_local,
    segment_enters,
    signed_area,
    validate_ring,
)

SQUARE = ((0.0, 0.0), (100.0, 0.0), (100.0, 100.0), (0.0, 100.0))


def octagon(cx: float, cy: float, r: float, phase: float = 0.0) -> tuple[tuple[float, float], ...]:
    return tuple(
        (cx + r * math.cos(phase + k * math.pi / 4), cy + r * math.sin(phase + k * math.pi / 4))
        for k in range(8)
    )


def test_a_valid_ring_is_kept_counter_clockwise_and_loses_its_closing_vertex() -> None:
    closed = (*reversed(SQUARE), SQUARE[-1])
    ring = validate_ring(closed)
    assert len(ring) == 4
    assert signed_area(ring) == pytest.approx(10_000.0)


@pytest.mark.parametrize(
    ("ring", "why"),
    [
        (((0.0, 0.0), (1.0, 0.0)), "at least 3"),
        (((0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)), "cross"),
        (((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)), "repeated"),
        (((0.0, 0.0), (10.0, 0.0), (20.0, 0.0)), "no area"),
        (((0.0, 0.0), (math.nan, 0.0), (0.0, 10.0)), "not finite"),
        (tuple((math.cos(k / 10), math.sin(k / 10)) for k in range(100)), "more than"),
    ],
)
def test_a_bad_ring_is_refused_with_its_reason(
    ring: tuple[tuple[float, float], ...], why: str
) -> None:
    with pytest.raises(ZoneError, match=why):
        validate_ring(ring)


def test_the_vertex_limit_is_allowed() -> None:
    ring = tuple(
        (math.cos(k * math.tau / MAX_ZONE_VERTICES), math.sin(k * math.tau / MAX_ZONE_VERTICES))
        for k in range(MAX_ZONE_VERTICES)
    )
    assert len(validate_ring([(1000 * x, 1000 * y) for x, y in ring])) == MAX_ZONE_VERTICES


def test_point_in_ring_of_a_concave_zone() -> None:
    u_shape = [(0.0, 0.0), (30.0, 0.0), (30.0, 30.0), (20.0, 30.0), (20.0, 10.0), (10.0, 10.0)]
    u_shape += [(10.0, 30.0), (0.0, 30.0)]
    assert point_in_ring((5.0, 20.0), u_shape)
    assert not point_in_ring((15.0, 20.0), u_shape)  # the bay
    assert point_in_ring((0.0, 15.0), u_shape)  # on an edge
    assert not point_in_ring((-1.0, 15.0), u_shape)


def test_segments_along_an_edge_or_through_a_vertex_do_not_enter() -> None:
    assert not segment_enters((-10.0, 0.0), (110.0, 0.0), SQUARE)  # along the edge
    assert not segment_enters((-10.0, -10.0), (0.0, 0.0), SQUARE)  # to a vertex
    assert not segment_enters((-50.0, 50.0), (50.0, -50.0), SQUARE)  # touching a vertex
    assert segment_enters((-10.0, 50.0), (110.0, 50.0), SQUARE)  # across
    assert segment_enters((0.0, 0.0), (100.0, 100.0), SQUARE)  # the diagonal, inside


def test_convex_hull_drops_the_bay_and_collinear_points() -> None:
    hull = convex_hull([*SQUARE, (50.0, 50.0), (50.0, 0.0)])
    assert set(hull) == set(SQUARE)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(20.0, 300.0),
    st.floats(0.0, math.tau),
    st.floats(0.0, 1.0),
    st.sampled_from([0, 1, 2, 3]),
)
def test_inflation_contains_every_point_within_the_distance(
    distance: float, angle: float, along: float, edge: int
) -> None:
    zone = ((0.0, 0.0), (400.0, 0.0), (500.0, 300.0), (-50.0, 200.0))
    inflated = inflate(zone, distance)
    a, b = zone[edge], zone[(edge + 1) % 4]
    base = (a[0] + along * (b[0] - a[0]), a[1] + along * (b[1] - a[1]))
    point = (
        base[0] + 0.999 * distance * math.cos(angle),
        base[1] + 0.999 * distance * math.sin(angle),
    )
    assert point_in_ring(point, inflated)


def test_inflation_stays_close_to_the_distance() -> None:
    inflated = inflate(octagon(0.0, 0.0, 500.0), 100.0)
    farthest = max(math.hypot(x, y) for x, y in inflated)
    assert 600.0 <= farthest <= 600.0 / math.cos(math.pi / 8) + 1e-6


def test_ring_to_local_puts_the_reference_at_the_origin() -> None:
    projection = MercatorProjection(42.0, -71.0)
    ring = ring_to_local(projection, [(42.0, -71.0), (42.01, -71.0), (42.0, -70.99)])
    assert ring[0] == pytest.approx((0.0, 0.0), abs=1e-6)
    assert ring[1][1] == pytest.approx(1111.0, rel=0.01)


def test_the_clearance_is_the_turn_radius_at_the_airspeed_held_plus_the_margin() -> None:
    limits = AircraftLimits()
    assert zone_clearance(limits, 22.0) == pytest.approx(limits.turn_radius(22.0) + ZONE_MARGIN_M)
    # Faster or slower than the aircraft can fly: the turn radius of the envelope's edge.
    top = limits.turn_radius(limits.max_airspeed) + ZONE_MARGIN_M
    assert zone_clearance(limits, 45.0) == pytest.approx(top)
    bottom = limits.turn_radius(limits.min_airspeed) + ZONE_MARGIN_M
    assert zone_clearance(limits, 0.0) == pytest.approx(bottom)
    slow, cruise, fast = (zone_clearance(limits, v) for v in (16.0, 22.0, 28.0))
    assert slow < cruise < fast


def test_the_zone_map_inflates_every_zone_by_the_clearance() -> None:
    limits = AircraftLimits()
    zones = (SQUARE, octagon(2000.0, 0.0, 300.0))
    inflated = zone_map(zones, limits, 25.0)
    clearance = zone_clearance(limits, 25.0)
    assert inflated.zones == tuple(inflate(zone, clearance) for zone in zones)
    assert inflated.zones == ZoneMap(zones, clearance).zones


def test_a_routes_time_is_its_legs_times_in_the_wind() -> None:
    assert legs_time([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0)], 10.0) == pytest.approx(20.0)
    # A 5 m/s wind from the west: the first leg downwind, the second across it.
    crab = math.sqrt(10.0**2 - 5.0**2)
    windy = legs_time([(0.0, 0.0), (100.0, 0.0), (100.0, 100.0)], 10.0, Wind(5.0, 0.0))
    assert windy == pytest.approx(100.0 / 15.0 + 100.0 / crab)


def test_a_clear_line_is_the_route() -> None:
    zones = ZoneMap([SQUARE], 10.0)
    route = zones.route((-100.0, -100.0), (-100.0, 500.0))
    assert route is not None and route.points == ((-100.0, 500.0),)
    assert not route.detours


def test_a_zone_between_start_and_goal_is_flown_around_by_the_shortest_side() -> None:
    zone = ((-100.0, -200.0), (100.0, -200.0), (100.0, 300.0), (-100.0, 300.0))
    zones = ZoneMap([zone], 50.0)
    route = zones.route((-1000.0, 0.0), (1000.0, 0.0))
    assert route is not None and route.detours
    legs = (route.start, *route.points)
    assert all(zones.clear(a, b) for a, b in itertools.pairwise(legs))
    assert all(y < 0 for _, y in route.points[:-1])  # the shorter way is south
    assert 2000.0 < route.length < 2000.0 + 2 * 250.0


def test_a_goal_walled_in_has_no_route() -> None:
    ring = octagon(0.0, 0.0, 1000.0)
    wall = [((x - 1, y - 1), (x + 1, y - 1), (x + 1, y + 1), (x - 1, y + 1)) for x, y in ring]
    zones = ZoneMap(wall, 450.0)
    assert zones.route((5000.0, 0.0), (0.0, 0.0)) is None


def test_a_start_inside_an_inflation_leaves_it() -> None:
    zones = ZoneMap([SQUARE], 100.0)
    route = zones.route((-50.0, 50.0), (300.0, 50.0))
    assert route is not None and route.detours


#: Up to three octagons (centre, radius, phase), and two points about them.
OCTAGONS = st.lists(
    st.tuples(st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(100, 600), st.floats(0, 1)),
    min_size=1,
    max_size=3,
)
POINT = st.tuples(st.floats(-5000, 5000), st.floats(-5000, 5000))
Octagons = list[tuple[float, float, float, float]]


def zones_between(
    octagons: Octagons, start: tuple[float, float], goal: tuple[float, float], inflation: float
) -> ZoneMap:
    """The octagons as zones, neither point inside one (else hypothesis tries again)."""
    zones = ZoneMap([octagon(x, y, r, p) for x, y, r, p in octagons], inflation)
    assume(not zones.containing(start) and not zones.containing(goal))
    return zones


def test_a_start_inside_a_zone_leaves_it_by_the_shortest_way_and_is_not_stranded() -> None:
    zones = ZoneMap([SQUARE], 100.0)
    # 10 m from the square's west edge: out of its 100 m inflation 110 m west, although
    # the goal lies east (leaving east would be 190 m inside).
    route = zones.route((10.0, 50.0), (500.0, 50.0))
    assert route is not None
    exit_x, exit_y = route.points[0]
    assert exit_x == pytest.approx(-101.0) and exit_y == pytest.approx(50.0)
    assert not zones.containing(route.points[0])
    assert route.points[-1] == (500.0, 50.0)
    for a, b in itertools.pairwise(route.points):  # around it from there, never across
        assert not segment_enters(a, b, zones.zones[0])


def brute_force_length(
    zones: ZoneMap, start: tuple[float, float], goal: tuple[float, float]
) -> float:
    """The shortest path over every sightline (no tangent pruning, the generic test)."""
    nodes = [start, *zones.vertices, goal]

    def clear(a: tuple[float, float], b: tuple[float, float]) -> bool:
        return not any(segment_enters(a, b, zone) for zone in zones.zones)

    best = [math.inf] * len(nodes)
    best[0] = 0.0
    done = [False] * len(nodes)
    for _ in nodes:
        i = min((d, k) for k, d in enumerate(best) if not done[k])[1]
        done[i] = True
        for j, node in enumerate(nodes):
            if not done[j] and clear(nodes[i], node):
                best[j] = min(best[j], best[i] + math.dist(nodes[i], node))
    return best[-1]


@settings(max_examples=40, deadline=None)
@given(OCTAGONS, POINT, POINT)
def test_the_route_is_out_of_every_zone_and_the_shortest_of_the_full_graph(
    octagons: Octagons, start: tuple[float, float], goal: tuple[float, float]
) -> None:
    zones = zones_between(octagons, start, goal, 120.0)
    route = zones.route(start, goal)
    # The graph pruned to tangent sightlines finds what every sightline would.
    full = brute_force_length(zones, start, goal)
    if route is None:
        assert full == math.inf
        return
    assert route.length == pytest.approx(full, rel=1e-9, abs=1e-6)
    assert route.length >= math.dist(start, goal) - 1e-6
    for a, b in itertools.pairwise((route.start, *route.points)):
        assert not any(segment_enters(a, b, zone) for zone in zones.zones)
