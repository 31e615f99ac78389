"""Tests of the analytic Dubins time to a point (fleet.geo.dubins)."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from fleet.geo.aircraft import AircraftLimits, turn_radius
from fleet.geo.dubins import dubins_path_length, dubins_time_in_wind, dubins_time_to_point
from fleet.geo.wind import CALM_AIR, Wind
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.guidance import fly_to_point
from tests.support.pure_pursuit import fly_pure_pursuit

LIMITS = AircraftLimits()
V = LIMITS.max_airspeed
R = turn_radius(V, LIMITS.bank_limit_deg)


def polar(dist: float, bearing_deg: float) -> tuple[float, float]:
    b = math.radians(bearing_deg)
    return dist * math.cos(b), dist * math.sin(b)


def test_dubins_straight_ahead_is_distance_over_speed() -> None:
    for d in (1.0, 500.0, 3000.0):
        assert dubins_time_to_point((0.0, 0.0), (V, 0.0), (d, 0.0), R) == pytest.approx(d / V)
    # Any heading: flying south-west.
    v = (-V / math.sqrt(2.0), -V / math.sqrt(2.0))
    assert dubins_time_to_point((10.0, 10.0), v, (-90.0, -90.0), R) == pytest.approx(
        100.0 * math.sqrt(2.0) / V
    )


def test_dubins_far_side_of_turn_circle_is_half_a_turn() -> None:
    half_turn = math.pi * R / V
    assert dubins_time_to_point((0.0, 0.0), (V, 0.0), (0.0, 2.0 * R), R) == pytest.approx(half_turn)
    assert dubins_time_to_point((0.0, 0.0), (V, 0.0), (0.0, -2.0 * R), R) == pytest.approx(
        half_turn
    )


def test_dubins_inside_turn_circle_uses_two_turns() -> None:
    # The centre of the left turn circle cannot be reached by turning left then going
    # straight; the path must exist (two turns) and be longer than the straight line.
    length = dubins_path_length((0.0, 0.0), 0.0, (0.0, R), R)
    assert math.isfinite(length)
    assert length > R


def test_dubins_stationary_aircraft() -> None:
    assert dubins_time_to_point((0.0, 0.0), (0.0, 0.0), (0.0, 0.0), R) == 0.0
    assert dubins_time_to_point((0.0, 0.0), (0.0, 0.0), (1.0, 0.0), R) == math.inf


@pytest.mark.parametrize("bearing", range(0, 360, 45))
def test_dubins_matches_flown_pure_pursuit(bearing: int) -> None:
    target = polar(1500.0, bearing)
    flown = fly_pure_pursuit((0.0, 0.0), (V, 0.0), target, LIMITS)
    assert flown is not None
    assert dubins_time_to_point((0.0, 0.0), (V, 0.0), target, R) == pytest.approx(flown, rel=2e-3)


coord = st.floats(-5000.0, 5000.0)


@settings(max_examples=200, deadline=None)
@given(
    px=coord,
    py=coord,
    heading=st.floats(-math.pi, math.pi),
    tx=coord,
    ty=coord,
    radius=st.floats(10.0, 500.0),
)
def test_dubins_bounds_and_invariance(
    px: float, py: float, heading: float, tx: float, ty: float, radius: float
) -> None:
    length = dubins_path_length((px, py), heading, (tx, ty), radius)
    dist = math.hypot(tx - px, ty - py)
    # Never shorter than the straight line; never longer than a full loop plus the
    # straight line from anywhere on the turn circle.
    assert length >= dist - 1e-6
    assert length <= dist + (2.0 * math.pi + 2.0) * radius + 1e-6
    # Translating and rotating the whole picture changes nothing, except at the "already
    # there" threshold (1e-6 radius), where the length jumps from a loop to zero and the
    # moved picture's rounding may put a point on either side (found by hypothesis).
    assume(abs(dist - 1e-6 * radius) > 1e-9)
    c, s = math.cos(0.7), math.sin(0.7)
    moved = dubins_path_length(
        (c * px - s * py + 100.0, s * px + c * py - 50.0),
        heading + 0.7,
        (c * tx - s * ty + 100.0, s * tx + c * ty - 50.0),
        radius,
    )
    assert moved == pytest.approx(length, rel=1e-6, abs=1e-6)


# -- in a steady wind ----------------------------------------------------------------


def test_wind_calm_is_the_still_air_time() -> None:
    target = polar(2000.0, 130.0)
    assert dubins_time_in_wind((0.0, 0.0), (V, 0.0), target, R, CALM_AIR) == (
        dubins_time_to_point((0.0, 0.0), (V, 0.0), target, R)
    )


def test_wind_straight_ahead_is_distance_over_ground_speed() -> None:
    assert dubins_time_in_wind((0.0, 0.0), (V, 0.0), (3000.0, 0.0), R, Wind(8.0, 0.0)) == (
        pytest.approx(3000.0 / (V + 8.0))
    )
    assert dubins_time_in_wind((0.0, 0.0), (V, 0.0), (3000.0, 0.0), R, Wind(-8.0, 0.0)) == (
        pytest.approx(3000.0 / (V - 8.0))
    )


def test_wind_as_fast_as_the_aircraft_never_arrives() -> None:
    assert dubins_time_in_wind((0.0, 0.0), (V, 0.0), (-900.0, 0.0), R, Wind(-V, 0.0)) == math.inf
    assert dubins_time_in_wind((1.0, 2.0), (V, 0.0), (1.0, 2.0), R, Wind(-V, 0.0)) == 0.0


@given(
    st.floats(300.0, 5000.0),
    st.floats(0.0, 360.0),
    st.floats(0.0, 0.6 * V),
    st.floats(0.0, 360.0),
)
@settings(max_examples=60, deadline=None)
def test_wind_time_is_the_first_root_of_the_virtual_target_equation(
    dist: float, bearing: float, wind_speed: float, wind_to: float
) -> None:
    wind = Wind(*polar(wind_speed, wind_to))
    target = polar(dist, bearing)
    t = dubins_time_in_wind((0.0, 0.0), (V, 0.0), target, R, wind)

    def excess(at: float) -> float:
        drifted = (target[0] - wind.east * at, target[1] - wind.north * at)
        return dubins_path_length((0.0, 0.0), 0.0, drifted, R) / V - at

    # Flyable at t (a path can be lengthened to arrive exactly then), not a moment before.
    assert excess(t) <= 1e-6
    assert excess(t - 1e-3) > 0.0
    # Never faster than a straight line at the best ground speed.
    assert t >= dist / (V + wind_speed) - 1e-9


@pytest.mark.parametrize("bearing", range(0, 360, 30))
def test_wind_time_matches_the_simulators_flight(bearing: int) -> None:
    wind = Wind(east=0.0, north=10.0)  # blows to the north
    speed = 22.0
    radius = turn_radius(speed, LIMITS.bank_limit_deg)
    target = polar(3000.0, bearing)  # x east, y north; the aircraft heads east
    state = AircraftState(x=0.0, y=0.0, alt=600.0, heading=math.pi / 2, airspeed=speed)
    flown = fly_to_point(
        state, target, limits=LIMITS, wind=SimWind(north=10.0), acceptance_radius=1.0
    )
    predicted = dubins_time_in_wind((0.0, 0.0), (speed, 0.0), target, radius, wind)
    # The simulator turns to a waypoint behind on the air mass's side, as the optimum does.
    assert predicted == pytest.approx(flown, rel=0.01)


@pytest.mark.parametrize("bearing", [165, 180, 195])
def test_wind_a_target_astern_at_1_km_is_flown_in_the_predicted_time(bearing: int) -> None:
    # Heading north in a 10 m/s wind blowing east: turning toward the bearing over the
    # ground would turn downwind, up to 21 % slower than predicted.
    speed = 22.0
    radius = turn_radius(speed, LIMITS.bank_limit_deg)
    b = math.radians(bearing)
    target = (1000.0 * math.sin(b), 1000.0 * math.cos(b))
    state = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=speed)
    flown = fly_to_point(
        state, target, limits=LIMITS, wind=SimWind(east=10.0), acceptance_radius=1.0
    )
    predicted = dubins_time_in_wind((0.0, 0.0), (0.0, speed), target, radius, Wind(10.0, 0.0))
    assert predicted == pytest.approx(flown, rel=0.02)
