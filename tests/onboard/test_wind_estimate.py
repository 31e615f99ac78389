"""Tests of the smoothed wind estimate (onboard.planner.wind_estimate)."""

from __future__ import annotations

import math
import random

import pytest

from fleet.geo.wind import CALM_AIR, Wind
from fleet.piccolo.telemetry import SensorBlock, Telemetry
from onboard.planner.wind_estimate import WindEstimate
from tests.onboard.core_harness import make_core
from tests.support.link_samples import sample_telemetry


def telemetry(wind_south: float, wind_west: float) -> Telemetry:
    sensor = SensorBlock(0.0, 0.0, 0.0, 22.0, wind_south=wind_south, wind_west=wind_west)
    return Telemetry(system_time_ms=0, sensor=sensor)


def test_first_estimate_is_taken_as_it_is() -> None:
    estimate = WindEstimate()
    assert estimate.value == CALM_AIR
    estimate.on_telemetry(telemetry(wind_south=-3.0, wind_west=4.0), now=10.0)
    assert estimate.value == Wind(east=-4.0, north=3.0)


def test_a_gust_moves_it_by_its_share_of_the_time_constant() -> None:
    estimate = WindEstimate(time_constant_s=20.0)
    estimate.update(Wind(10.0, 0.0), 0.0)
    estimate.update(Wind(20.0, 0.0), 1.0)  # a 1 s gust of +10 m/s
    assert estimate.value.east == pytest.approx(10.0 + 10.0 * (1.0 - math.exp(-1.0 / 20.0)))


def test_gusts_average_out_to_the_mean() -> None:
    rng = random.Random(3)
    estimate = WindEstimate()
    for i in range(2400):  # 10 minutes at 4 Hz, gusts of +-3 m/s
        estimate.update(Wind(8.0 + rng.gauss(0.0, 3.0), -2.0 + rng.gauss(0.0, 3.0)), i * 0.25)
    assert estimate.value.east == pytest.approx(8.0, abs=0.8)
    assert estimate.value.north == pytest.approx(-2.0, abs=0.8)


def test_corrupt_estimates_are_dropped_and_counted() -> None:
    estimate = WindEstimate()
    estimate.update(Wind(5.0, 0.0), 0.0)
    estimate.update(Wind(math.nan, 0.0), 1.0)
    estimate.update(Wind(300.0, 0.0), 2.0)
    estimate.update(Wind(5.0, 0.0), 0.5)  # a clock gone back: no weight, no crash
    assert estimate.value == Wind(5.0, 0.0)
    assert (estimate.samples, estimate.dropped) == (2, 2)
    estimate.on_telemetry(Telemetry(system_time_ms=0), 3.0)  # no sensor block: nothing
    assert estimate.samples == 2


def test_the_module_plans_with_the_smoothed_wind_not_the_latest_report() -> None:
    core, _ = make_core()  # its first telemetry at 0 s
    reports = [telemetry(0.0, -10.0), telemetry(0.0, -20.0)]  # 10 m/s east, then a gust
    expected = WindEstimate()
    expected.on_telemetry(sample_telemetry(), 0.0)
    for now, report in zip((10.0, 11.0), reports, strict=True):
        core.on_telemetry(report, now)
        expected.on_telemetry(report, now)
    assert core.wind == expected.value
    assert core.wind.east < 20.0  # the 1 s gust weighed by its share, not taken whole
