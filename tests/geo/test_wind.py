"""Tests of straight flight in a steady wind (fleet.geo.wind)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.geo.wind import (
    CALM_AIR,
    Wind,
    air_velocity,
    airspeed,
    ground_speed_along,
    leg_time,
    straight_leg_time,
)
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.guidance import fly_to_point

V = 22.0


def test_still_air_is_distance_over_airspeed() -> None:
    assert straight_leg_time(37.0, 2200.0, V, CALM_AIR) == pytest.approx(100.0)
    assert leg_time((5.0, 5.0), (5.0, 5.0), V, Wind(3.0, 4.0)) == 0.0


def test_head_tail_and_cross_winds() -> None:
    westerly = Wind(east=10.0, north=0.0)  # blows to the east
    assert straight_leg_time(90.0, 3200.0, V, westerly) == pytest.approx(100.0)  # tailwind
    assert straight_leg_time(270.0, 1200.0, V, westerly) == pytest.approx(100.0)  # headwind
    crossing = math.sqrt(V * V - 100.0)
    assert straight_leg_time(0.0, crossing * 100.0, V, westerly) == pytest.approx(100.0)
    assert straight_leg_time(180.0, crossing * 100.0, V, westerly) == pytest.approx(100.0)


def test_a_leg_that_cannot_be_made_good_takes_forever() -> None:
    gale = Wind(east=25.0, north=0.0)
    assert straight_leg_time(0.0, 1000.0, V, gale) == math.inf  # crosswind faster than V
    assert straight_leg_time(270.0, 1000.0, V, gale) == math.inf  # headwind faster than V
    assert straight_leg_time(270.0, 1000.0, V, Wind(east=V)) == math.inf  # no ground speed
    assert ground_speed_along((0.0, 1.0), V, gale) == 0.0


def test_piccolo_components_point_the_other_way() -> None:
    # wind_south / wind_west are the components toward south and west.
    assert Wind.from_piccolo(wind_south=-3.0, wind_west=4.0) == Wind(east=-4.0, north=3.0)
    assert not CALM_AIR
    assert Wind(0.0, 1.0)


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="non-zero"):
        ground_speed_along((0.0, 0.0), V, CALM_AIR)
    with pytest.raises(ValueError, match=">= 0"):
        straight_leg_time(0.0, -1.0, V, CALM_AIR)


@given(
    st.floats(0.0, 360.0),
    st.floats(0.0, 0.95 * V),
    st.floats(0.0, 360.0),
)
def test_the_crabbed_air_velocity_has_the_airspeed(
    bearing: float, wind_speed: float, wind_to: float
) -> None:
    wind = Wind(
        wind_speed * math.sin(math.radians(wind_to)), wind_speed * math.cos(math.radians(wind_to))
    )
    u = (math.sin(math.radians(bearing)), math.cos(math.radians(bearing)))
    speed = ground_speed_along(u, V, wind)
    assert speed >= V - wind_speed - 1e-9
    air = (speed * u[0] - wind.east, speed * u[1] - wind.north)
    assert math.hypot(*air) == pytest.approx(V, rel=1e-9)


@pytest.mark.parametrize("bearing", [0.0, 60.0, 135.0, 225.0, 300.0])
def test_matches_the_simulators_straight_flight(bearing: float) -> None:
    wind = Wind(east=-6.0, north=8.0)
    rad = math.radians(bearing)
    # Already on course (crabbed), 3 km out: the simulator flies it straight.
    gs = ground_speed_along((math.sin(rad), math.cos(rad)), V, wind)
    air_east, air_north = gs * math.sin(rad) - wind.east, gs * math.cos(rad) - wind.north
    state = AircraftState(
        x=0.0, y=0.0, alt=600.0, heading=math.atan2(air_east, air_north) % math.tau, airspeed=V
    )
    target = (3000.0 * math.sin(rad), 3000.0 * math.cos(rad))
    flown = fly_to_point(
        state, target, wind=SimWind(north=wind.north, east=wind.east), acceptance_radius=1.0
    )
    assert flown == pytest.approx(straight_leg_time(bearing, 2999.0, V, wind), rel=2e-3)


def test_at_most_keeps_the_direction() -> None:
    assert Wind(3.0, 4.0).at_most(10.0) == Wind(3.0, 4.0)
    capped = Wind(6.0, 8.0).at_most(5.0)
    assert capped.east == pytest.approx(3.0) and capped.north == pytest.approx(4.0)


def test_the_airspeed_is_the_ground_velocity_less_the_wind() -> None:
    # Flying east at 32 m/s over the ground with a 12 m/s westerly: 20 m/s through the air.
    assert air_velocity((32.0, 0.0), Wind(east=12.0)) == (20.0, 0.0)
    assert airspeed((32.0, 0.0), Wind(east=12.0)) == pytest.approx(20.0)
    # Crabbing north across it: the air velocity points upwind of the track.
    assert air_velocity((0.0, 16.0), Wind(east=12.0)) == (-12.0, 16.0)
    assert airspeed((0.0, 16.0), Wind(east=12.0)) == pytest.approx(20.0)
    assert airspeed((3.0, -4.0), CALM_AIR) == pytest.approx(5.0)


@given(
    st.floats(-40.0, 40.0), st.floats(-40.0, 40.0), st.floats(-20.0, 20.0), st.floats(-20.0, 20.0)
)
def test_flying_the_air_velocity_in_the_wind_gives_the_ground_velocity(
    east: float, north: float, wind_east: float, wind_north: float
) -> None:
    wind = Wind(wind_east, wind_north)
    air = air_velocity((east, north), wind)
    assert air[0] + wind.east == pytest.approx(east, abs=1e-9)
    assert air[1] + wind.north == pytest.approx(north, abs=1e-9)
    assert airspeed((east, north), wind) == pytest.approx(math.hypot(*air))
