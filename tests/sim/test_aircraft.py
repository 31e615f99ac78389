"""Pure tests of the simulated aircraft, its guidance and its flight plan (in-process, fast)."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.geo.aircraft import GRAVITY, AircraftLimits, turn_radius
from fleet.geo.mercator import MercatorProjection
from fleet.piccolo.waypoint import Waypoint
from fleet.sim.aircraft import CALM, AircraftState, Command, Wind, step
from fleet.sim.flight_plan import FlightPlan, FlightPlanError, closed_chain, racetrack
from fleet.sim.guidance import (
    STEP_S,
    GuidanceSettings,
    UnreachedError,
    bank_command,
    fly_to_point,
    fly_until_arrival,
)

DT = STEP_S
LIMITS = AircraftLimits()


def fly(
    state: AircraftState,
    command: Command,
    seconds: float,
    wind: Wind = CALM,
    limits: AircraftLimits = LIMITS,
) -> list[AircraftState]:
    """States after each step of `seconds` under a constant command (first is `state`)."""
    states = [state]
    for _ in range(round(seconds / DT)):
        states.append(step(states[-1], command, limits, wind, DT))
    return states


def circumradius(a: AircraftState, b: AircraftState, c: AircraftState) -> float:
    ab = math.hypot(b.x - a.x, b.y - a.y)
    bc = math.hypot(c.x - b.x, c.y - b.y)
    ca = math.hypot(a.x - c.x, a.y - c.y)
    area2 = abs((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y))
    return ab * bc * ca / (2.0 * area2)


def level(heading_deg: float = 90.0, airspeed: float = 22.0, alt: float = 500.0) -> AircraftState:
    return AircraftState(0.0, 0.0, alt, math.radians(heading_deg), airspeed)


# -- dynamics ---------------------------------------------------------------------------


@pytest.mark.parametrize("airspeed", [15.0, 22.0, 30.0])
@pytest.mark.parametrize("bank_limit", [20.0, 30.0, 45.0])
def test_flown_turn_radius_is_v2_over_g_tan_bank(airspeed: float, bank_limit: float) -> None:
    limits = AircraftLimits(bank_limit_deg=bank_limit)
    # Ask for more bank than allowed: the aircraft must turn at the limit, no tighter.
    command = Command(bank=math.radians(80.0), airspeed=airspeed, altitude=500.0)
    expected = turn_radius(airspeed, bank_limit)
    period = 2.0 * math.pi * expected / airspeed
    states = fly(level(airspeed=airspeed), command, 5.0 + 1.5 * period, limits=limits)
    steady = states[round(5.0 / DT) :]  # after the roll-in
    third = round(period / 3.0 / DT)
    radii = [circumradius(steady[i], steady[i + third], steady[i + 2 * third]) for i in (0, third)]
    for radius in radii:
        assert radius == pytest.approx(expected, rel=0.05)
        # The integration is in fact far better than the 5 % required.
        assert radius == pytest.approx(expected, rel=1e-3)
    assert max(abs(s.bank) for s in states) == pytest.approx(math.radians(bank_limit))


def test_roll_rate_limits_how_fast_the_bank_builds() -> None:
    states = fly(level(), Command(math.radians(30.0), 22.0, 500.0), 2.0)
    roll_time = 30.0 / LIMITS.roll_rate_deg
    at_half = states[round(roll_time / 2 / DT)]
    assert math.degrees(at_half.bank) == pytest.approx(15.0, abs=1.0)
    assert math.degrees(states[-1].bank) == pytest.approx(30.0)


def test_airspeed_follows_its_command_at_a_bounded_rate_within_the_envelope() -> None:
    fast = fly(level(airspeed=22.0), Command(0.0, 45.0, 500.0), 12.0)
    assert fast[round(4.0 / DT)].airspeed == pytest.approx(26.0, abs=0.05)
    assert fast[-1].airspeed == pytest.approx(LIMITS.max_airspeed)
    slow = fly(level(airspeed=22.0), Command(0.0, 5.0, 500.0), 12.0)
    assert slow[-1].airspeed == pytest.approx(LIMITS.min_airspeed)
    steps = [abs(b.airspeed - a.airspeed) for a, b in itertools.pairwise(fast)]
    assert max(steps) <= LIMITS.airspeed_rate * DT + 1e-12


def test_altitude_hold_climbs_at_the_rate_limit_and_settles() -> None:
    states = fly(level(alt=500.0), Command(0.0, 22.0, 800.0), 150.0)
    assert max(s.climb_rate for s in states) == pytest.approx(LIMITS.climb_rate)
    # 300 m at 3 m/s is at least 100 s.
    assert states[round(90.0 / DT)].alt < 800.0 - 20.0
    assert states[-1].alt == pytest.approx(800.0, abs=0.5)
    assert max(s.alt for s in states) <= 800.0 + 1e-6
    descent = fly(level(alt=500.0), Command(0.0, 22.0, 200.0), 20.0)
    assert min(s.climb_rate for s in descent) == pytest.approx(-LIMITS.climb_rate)


def test_wind_drifts_a_straight_ground_track() -> None:
    wind = Wind(north=3.0, east=-4.0)
    states = fly(level(heading_deg=0.0, airspeed=20.0), Command(0.0, 20.0, 500.0), 100.0, wind)
    end = states[-1]
    assert end.x == pytest.approx(-4.0 * 100.0, abs=1e-6)
    assert end.y == pytest.approx((20.0 + 3.0) * 100.0, abs=1e-6)
    assert end.ground_velocity(wind) == pytest.approx((23.0, -4.0))


def test_wind_drifts_a_circle_by_wind_times_time() -> None:
    # Over whole revolutions the air-relative circle closes, so the aircraft ends up
    # displaced by exactly the wind's drift.
    wind = Wind(north=-2.5, east=6.0)
    airspeed = 20.0
    start = level(heading_deg=45.0, airspeed=airspeed)
    banked = AircraftState(start.x, start.y, start.alt, start.heading, airspeed, math.radians(30))
    rate = banked.heading_rate
    revolution_steps = 2.0 * math.pi / rate / DT
    steps = round(3 * revolution_steps)
    states = fly(banked, Command(math.radians(30.0), airspeed, 500.0), steps * DT, wind)
    seconds = steps * DT
    # The step count is rounded to whole steps: allow for the part-step of arc.
    slack = airspeed * DT
    assert states[-1].x == pytest.approx(wind.east * seconds, abs=slack)
    assert states[-1].y == pytest.approx(wind.north * seconds, abs=slack)


def test_dynamics_are_deterministic() -> None:
    command = Command(math.radians(25.0), 27.0, 650.0)
    wind = Wind(1.5, -2.0)
    assert fly(level(), command, 30.0, wind) == fly(level(), command, 30.0, wind)


# -- guidance ----------------------------------------------------------------------------


def test_straight_ahead_arrival_is_distance_over_speed() -> None:
    arrival = fly_to_point(level(heading_deg=90.0), (3000.0, 0.0))
    assert arrival == pytest.approx((3000.0 - 60.0) / 22.0, abs=DT)


def test_a_point_behind_costs_a_half_turn_at_the_bank_limit() -> None:
    arrival, state = fly_until_arrival(level(heading_deg=90.0), (-2000.0, 0.0))
    radius = turn_radius(22.0, LIMITS.bank_limit_deg)
    half_turn = math.pi * radius / 22.0
    assert arrival > half_turn + (2000.0 - 60.0) / 22.0
    assert arrival < half_turn + (2000.0 + 2 * radius) / 22.0 + 10.0
    assert abs(math.degrees(state.heading) - 270.0) < 15.0


def test_guidance_banks_at_the_limit_for_a_large_course_error() -> None:
    assert bank_command(level(heading_deg=0.0), (1000.0, -1000.0), LIMITS) == pytest.approx(
        LIMITS.bank_limit
    )
    assert bank_command(level(heading_deg=0.0), (-1000.0, -1000.0), LIMITS) == pytest.approx(
        -LIMITS.bank_limit
    )
    assert bank_command(level(heading_deg=0.0), (0.0, 1000.0), LIMITS) == pytest.approx(0.0)


@pytest.mark.parametrize("target", [(0.0, 50.0), (0.0, 100.0), (30.0, -120.0), (10.0, 170.0)])
def test_a_point_inside_the_turning_circle_is_still_reached(target: tuple[float, float]) -> None:
    # Heading east, the turning circles are centred 85 m north and south: pure pursuit
    # would orbit these points forever.
    assert fly_to_point(level(heading_deg=90.0), target, max_time=120.0) < 60.0


def test_wind_is_compensated_on_the_way_to_a_point() -> None:
    wind = Wind(north=0.0, east=-8.0)
    arrival, state = fly_until_arrival(
        level(heading_deg=0.0, airspeed=20.0), (0.0, 3000.0), wind=wind
    )
    # Crabbing into a crosswind: heading east of north, ground track straight north.
    assert 0.0 < math.degrees(state.heading) < 45.0
    ground = math.sqrt(20.0**2 - 8.0**2)
    assert arrival == pytest.approx((3000.0 - 60.0) / ground, rel=0.05)


def test_unreached_point_raises() -> None:
    with pytest.raises(UnreachedError, match="not within"):
        fly_to_point(level(), (50_000.0, 0.0), max_time=10.0)


@settings(max_examples=25, deadline=None)
@given(
    heading=st.floats(0.0, 359.9),
    bearing=st.floats(0.0, 359.9),
    distance=st.floats(0.0, 4000.0),
    airspeed=st.floats(15.0, 30.0),
    wind_north=st.floats(-8.0, 8.0),
    wind_east=st.floats(-8.0, 8.0),
)
def test_every_point_is_reached_in_bounded_time(
    heading: float,
    bearing: float,
    distance: float,
    airspeed: float,
    wind_north: float,
    wind_east: float,
) -> None:
    wind = Wind(wind_north, wind_east)
    target = (
        distance * math.sin(math.radians(bearing)),
        distance * math.cos(math.radians(bearing)),
    )
    worst_ground = airspeed - wind.speed
    radius = turn_radius(airspeed + wind.speed, LIMITS.bank_limit_deg)
    bound = (distance + 4.0 * math.pi * radius) / worst_ground + 30.0
    arrival = fly_to_point(
        level(heading_deg=heading, airspeed=airspeed), target, wind=wind, max_time=bound
    )
    assert arrival <= bound


def test_guidance_settings_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match="acceptance"):
        GuidanceSettings(acceptance_radius=0.0)


def test_coordinated_turn_rate() -> None:
    state = AircraftState(0.0, 0.0, 0.0, 0.0, 20.0, math.radians(30.0))
    assert state.heading_rate == pytest.approx(GRAVITY * math.tan(math.radians(30.0)) / 20.0)


# -- flight plan -------------------------------------------------------------------------


def test_closed_chain_links_each_waypoint_to_the_next_and_back() -> None:
    chain = closed_chain([(1.0, 2.0, 100.0), (1.1, 2.0, 100.0), (1.1, 2.1, 120.0)], first_index=5)
    assert [(w.index, w.next_index) for w in chain] == [(5, 6), (6, 7), (7, 5)]
    plan = FlightPlan(chain)
    assert plan.chain(6) == [6, 7, 5]
    assert plan.is_closed_chain(5)


def test_chain_stops_at_a_missing_next() -> None:
    plan = FlightPlan([Waypoint(index=0, next_index=1, lat=0.0, lon=0.0, alt=0.0)])
    assert plan.chain(0) == [0]
    assert not plan.is_closed_chain(0)
    assert plan.chain(42) == []
    plan.store(Waypoint(index=1, next_index=0, lat=0.0, lon=0.0, alt=0.0))
    assert plan.is_closed_chain(1)


def test_waypoint_indices_are_0_to_99() -> None:
    plan = FlightPlan()
    with pytest.raises(FlightPlanError, match="index 100"):
        plan.store(Waypoint(index=100, next_index=0, lat=0.0, lon=0.0, alt=0.0))
    with pytest.raises(FlightPlanError, match="next 120"):
        plan.store(Waypoint(index=3, next_index=120, lat=0.0, lon=0.0, alt=0.0))
    with pytest.raises(FlightPlanError, match="do not fit"):
        closed_chain([(0.0, 0.0, 0.0)] * 101)


def test_default_racetrack_lies_ahead_and_to_the_right() -> None:
    lat, lon, heading = 35.72, -120.79, 90.0
    projection = MercatorProjection(lat, lon)
    corners = [projection.to_xy(c[0], c[1]) for c in racetrack(lat, lon, 600.0, heading)]
    expected = [(3000.0, 0.0), (3000.0, -1000.0), (0.0, -1000.0), (0.0, 0.0)]
    for (x, y), (ex, ey) in zip(corners, expected, strict=True):
        assert x == pytest.approx(ex, abs=0.01)
        assert y == pytest.approx(ey, abs=0.01)
