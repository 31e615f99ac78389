"""Tests of the angle wrapping helpers (fleet.geo.angles)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.geo.angles import TWO_PI, wrap_degrees, wrap_pi, wrap_two_pi

_angle = st.floats(-1e4, 1e4)


@given(_angle)
def test_wrap_two_pi_lands_in_its_range_on_the_same_direction(angle: float) -> None:
    wrapped = wrap_two_pi(angle)
    assert 0.0 <= wrapped < TWO_PI
    assert math.cos(wrapped) == pytest.approx(math.cos(angle), abs=1e-9)
    assert math.sin(wrapped) == pytest.approx(math.sin(angle), abs=1e-9)


@given(_angle)
def test_wrap_pi_lands_in_its_range_on_the_same_direction(angle: float) -> None:
    wrapped = wrap_pi(angle)
    assert -math.pi <= wrapped < math.pi
    assert math.cos(wrapped) == pytest.approx(math.cos(angle), abs=1e-9)
    assert math.sin(wrapped) == pytest.approx(math.sin(angle), abs=1e-9)


@given(st.floats(-1e5, 1e5))
def test_wrap_degrees_lands_in_its_range(angle: float) -> None:
    wrapped = wrap_degrees(angle)
    assert -180.0 <= wrapped < 180.0
    assert (wrapped - angle) / 360.0 == pytest.approx(round((wrapped - angle) / 360.0), abs=1e-9)


def test_the_edges_have_one_representative() -> None:
    assert wrap_two_pi(TWO_PI) == 0.0
    # A tiny negative angle would come out as 2 pi itself from a bare `%`.
    assert wrap_two_pi(-1e-18) == 0.0
    assert wrap_pi(math.pi) == -math.pi
    assert wrap_degrees(180.0) == -180.0
    assert wrap_degrees(-180.0) == -180.0
    assert wrap_degrees(540.0) == -180.0
