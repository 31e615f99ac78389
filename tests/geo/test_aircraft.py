"""Tests of the flight envelope and the turn geometry (fleet.geo.aircraft)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.geo.aircraft import GRAVITY, AircraftLimits, turn_radius


def test_turn_radius_is_v2_over_g_tan_bank() -> None:
    assert turn_radius(30.0, 30.0) == pytest.approx(30.0**2 / (9.80665 * math.tan(math.pi / 6)))


def test_a_wings_level_aircraft_does_not_turn() -> None:
    assert turn_radius(30.0, 0.0) == math.inf


@given(st.floats(1.0, 100.0), st.floats(1.0, 89.0))
def test_a_left_and_a_right_turn_have_the_same_radius(speed: float, bank: float) -> None:
    assert turn_radius(speed, -bank) == turn_radius(speed, bank)


def test_limits_give_the_turn_at_the_bank_limit() -> None:
    limits = AircraftLimits(bank_limit_deg=45.0)
    assert limits.bank_limit == pytest.approx(math.pi / 4)
    assert limits.max_accel == pytest.approx(GRAVITY)
    assert limits.turn_radius(20.0) == pytest.approx(400.0 / GRAVITY)
    # The lateral acceleration of that turn is v^2 / r.
    assert 20.0**2 / limits.turn_radius(20.0) == pytest.approx(limits.max_accel)


def test_airspeed_is_clamped_into_the_envelope() -> None:
    limits = AircraftLimits(min_airspeed=15.0, max_airspeed=30.0)
    assert limits.clamp_airspeed(0.0) == 15.0
    assert limits.clamp_airspeed(22.0) == 22.0
    assert limits.clamp_airspeed(45.0) == 30.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"min_airspeed": 0.0}, "airspeed"),
        ({"min_airspeed": 31.0}, "airspeed"),
        ({"min_airspeed": 30.0, "max_airspeed": 15.0}, "airspeed"),
        ({"max_airspeed": math.inf}, "airspeed"),
        ({"bank_limit_deg": 0.0}, "bank"),
        ({"bank_limit_deg": 90.0}, "bank"),
        ({"bank_limit_deg": 95.0}, "bank"),
        ({"climb_rate": 0.0}, "climb_rate"),
        ({"roll_rate_deg": math.nan}, "roll_rate_deg"),
    ],
)
def test_limits_refuse_nonsense(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        AircraftLimits(**kwargs)
