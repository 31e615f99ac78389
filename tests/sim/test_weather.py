"""Tests of the simulator's weather (fleet.sim.weather) and its scenario table."""

from __future__ import annotations

import dataclasses
import math
import statistics
from pathlib import Path

import pytest

from fleet.sim.aircraft import Wind
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.scenario import parse_scenario
from fleet.sim.uav_spec import UavSpec
from fleet.sim.weather import Weather, WeatherSpec
from tests.sim.test_scenario import VALID

DT = 0.02
WINDY = WeatherSpec(
    mean=Wind(north=0.0, east=10.0),
    drift_speed=1.5,
    drift_direction_deg=15.0,
    drift_period_s=600.0,
    gust=1.0,
    gust_time_s=4.0,
    estimate_lag_s=10.0,
    estimate_error=0.5,
    seed=7,
)


def fly(weather: Weather, seconds: float) -> list[tuple[Wind, Wind]]:
    """(true wind, reported estimate) once a second."""
    out = []
    per_second = round(1.0 / DT)
    for i in range(round(seconds / DT)):
        weather.advance(DT)
        if i % per_second == per_second - 1:
            out.append((weather.wind, weather.estimate))
    return out


def test_a_steady_wind_never_changes_and_is_reported_exactly() -> None:
    weather = Weather(WeatherSpec(mean=Wind(north=3.0, east=-4.0)), piccolo_id=7)
    samples = fly(weather, 60.0)
    assert all(true == reported == Wind(3.0, -4.0) for true, reported in samples)


def test_the_same_seed_gives_the_same_weather_and_another_seed_does_not() -> None:
    first = fly(Weather(WINDY, 74), 120.0)
    assert fly(Weather(WINDY, 74), 120.0) == first
    assert fly(Weather(WINDY, 112), 120.0) != first  # gusts are each aircraft's own
    other = dataclasses.replace(WINDY, seed=8)
    assert fly(Weather(other, 74), 120.0) != first


def test_gusts_have_their_spread_and_the_mean_drifts_slowly() -> None:
    samples = fly(Weather(WINDY, 74), 1800.0)
    east = [true.east for true, _ in samples]
    north = [true.north for true, _ in samples]
    assert statistics.mean(east) == pytest.approx(10.0, abs=1.0)
    # Gusts (1 m/s) plus the direction's drift (+-15 degrees of 10 m/s) across the wind.
    assert 0.8 < statistics.pstdev(north) < 2.5
    speeds = [math.hypot(t.east, t.north) for t, _ in samples]
    assert max(speeds) < WINDY.strongest


def test_the_estimate_lags_and_errs() -> None:
    weather = Weather(WINDY, 74)
    samples = fly(weather, 900.0)
    errors = [math.hypot(t.east - r.east, t.north - r.north) for t, r in samples]
    # Never exact, never wild: the bias (0.5 m/s per component) plus the lag behind gusts.
    assert 0.1 < statistics.median(errors) < 2.5
    # Averaged over minutes the estimate is the wind, give or take its bias.
    mean_true = statistics.mean(t.east for t, _ in samples)
    mean_reported = statistics.mean(r.east for _, r in samples)
    assert mean_reported == pytest.approx(mean_true, abs=1.5)


def test_the_autopilot_flies_in_its_weather_and_reports_the_estimate() -> None:
    uav = UavSpec(74, 35.72, -120.79, 600.0, 0.0, 22.0)
    autopilot = SimulatedAutopilot(uav, AutopilotSettings(), WINDY)
    for _ in range(500):  # 10 s
        autopilot.step()
    sensor = autopilot.telemetry().sensor
    gps = autopilot.telemetry().gps
    assert sensor is not None and gps is not None
    estimate = autopilot.weather.estimate
    assert (sensor.wind_south, sensor.wind_west) == (-estimate.north, -estimate.east)
    # 22 m/s through the air: the ground velocity less the true wind (the estimate differs).
    true = autopilot.weather.wind
    air = math.hypot(gps.vel_east - true.east, gps.vel_north - true.north)
    assert air == pytest.approx(22.0, abs=0.05)
    assert estimate != true


# The scenario tests' valid file, in a windier sky.
SCENARIO = VALID.replace(
    "[wind]\nnorth = 1.0\neast = -2.0\n",
    "[wind]\neast = 8.0\ndrift_speed = 1.0\ndrift_direction = 10.0\ngust = 1.0\n"
    "estimate_error = 0.3\nseed = 3\n",
)


def test_the_scenario_table_gives_the_weather(tmp_path: Path) -> None:
    assert SCENARIO != VALID
    scenario = parse_scenario(SCENARIO, "windy.toml", tmp_path)
    assert scenario.wind == Wind(north=0.0, east=8.0)
    weather = scenario.weather
    assert (weather.drift_speed, weather.drift_direction_deg, weather.gust) == (1.0, 10.0, 1.0)
    assert (weather.estimate_error, weather.seed, weather.drift_period_s) == (0.3, 3, 1800.0)
