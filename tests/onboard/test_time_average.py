"""Tests of the time average and the aircraft's clock (onboard.time_average)."""

from __future__ import annotations

import math

import pytest

from onboard.time_average import AircraftClock, TimeAverage


def test_a_sample_moves_the_average_by_its_share_of_the_time_constant() -> None:
    average = TimeAverage(20.0)
    assert average.add((10.0, -2.0), 5.0) == (10.0, -2.0)  # the first, as it is
    moved = average.add((20.0, 2.0), 7.0)
    weight = 1.0 - math.exp(-2.0 / 20.0)
    assert moved == pytest.approx((10.0 + 10.0 * weight, -2.0 + 4.0 * weight))
    assert average.add((99.0, 99.0), 7.0) == pytest.approx(moved)  # no time: no weight


def test_a_time_gone_back_another_shape_or_a_reset_starts_again() -> None:
    average = TimeAverage(20.0)
    average.add((10.0,), 5.0)
    assert average.add((4.0,), 1.0) == (4.0,)  # a restarted clock: not a negative weight
    assert average.add((1.0, 2.0), 2.0) == (1.0, 2.0)
    average.reset()
    assert (average.value, average.at) == (None, None)
    assert TimeAverage(0.0).add((3.0,), 1.0) == (3.0,)
    follow = TimeAverage(0.0)
    follow.add((3.0,), 1.0)
    assert follow.add((5.0,), 2.0) == (5.0,)  # no time constant: each sample as it is


def test_the_aircraft_clock_runs_on_the_autopilot_s_time_and_never_goes_back() -> None:
    clock = AircraftClock()
    assert clock.tick(10_000, 100.0) == 0.0  # the first telemetry: time zero
    assert clock.tick(14_000, 101.0) == pytest.approx(4.0)  # speedup 4: the aircraft's
    # A restarted (or wrapped) autopilot clock: the wall's second, not a jump back.
    assert clock.tick(500, 102.0) == pytest.approx(5.0)
    assert clock.tick(1_500, 102.5) == pytest.approx(6.0)
    # A source whose clock never moves: the wall's time; a wall gone back: no time.
    assert clock.tick(1_500, 104.5) == pytest.approx(8.0)
    assert clock.tick(1_500, 103.0) == pytest.approx(8.0)
