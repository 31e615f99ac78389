"""Tests for the Mercator projection about a reference point (thesis 2.8.1)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.geo.mercator import WGS84_A, WGS84_F, MercatorProjection

_ref_lat = st.floats(min_value=-70.0, max_value=70.0)
_ref_lon = st.floats(min_value=-180.0, max_value=180.0)
_bearing = st.floats(min_value=0.0, max_value=2.0 * math.pi)


def vincenty_inverse_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Geodesic distance on WGS-84 (Vincenty 1975), an independent reference.

    Written from the published formulas, not from fleet.geo.mercator; it converges for every
    pair that is not nearly antipodal, which covers these short distances.
    """
    a, f = WGS84_A, WGS84_F
    b = a * (1.0 - f)
    u1 = math.atan((1.0 - f) * math.tan(math.radians(lat1)))
    u2 = math.atan((1.0 - f) * math.tan(math.radians(lat2)))
    big_l = math.radians((lon2 - lon1 + 180.0) % 360.0 - 180.0)
    sin_u1, cos_u1, sin_u2, cos_u2 = math.sin(u1), math.cos(u1), math.sin(u2), math.cos(u2)
    lam = big_l
    for _ in range(200):
        sin_lam, cos_lam = math.sin(lam), math.cos(lam)
        sin_sigma = math.hypot(cos_u2 * sin_lam, cos_u1 * sin_u2 - sin_u1 * cos_u2 * cos_lam)
        if sin_sigma == 0.0:
            return 0.0
        cos_sigma = sin_u1 * sin_u2 + cos_u1 * cos_u2 * cos_lam
        sigma = math.atan2(sin_sigma, cos_sigma)
        sin_alpha = cos_u1 * cos_u2 * sin_lam / sin_sigma
        cos2_alpha = 1.0 - sin_alpha * sin_alpha
        cos_2sm = cos_sigma - 2.0 * sin_u1 * sin_u2 / cos2_alpha if cos2_alpha else 0.0
        c = f / 16.0 * cos2_alpha * (4.0 + f * (4.0 - 3.0 * cos2_alpha))
        lam_prev = lam
        lam = big_l + (1.0 - c) * f * sin_alpha * (
            sigma + c * sin_sigma * (cos_2sm + c * cos_sigma * (-1.0 + 2.0 * cos_2sm**2))
        )
        if abs(lam - lam_prev) < 1e-13:
            break
    u_sq = cos2_alpha * (a * a - b * b) / (b * b)
    big_a = 1.0 + u_sq / 16384.0 * (4096.0 + u_sq * (-768.0 + u_sq * (320.0 - 175.0 * u_sq)))
    big_b = u_sq / 1024.0 * (256.0 + u_sq * (-128.0 + u_sq * (74.0 - 47.0 * u_sq)))
    delta_sigma = (
        big_b
        * sin_sigma
        * (
            cos_2sm
            + big_b
            / 4.0
            * (
                cos_sigma * (-1.0 + 2.0 * cos_2sm**2)
                - big_b / 6.0 * cos_2sm * (-3.0 + 4.0 * sin_sigma**2) * (-3.0 + 4.0 * cos_2sm**2)
            )
        )
    )
    return b * big_a * (sigma - delta_sigma)


def _ground_error_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    # Degrees to metres with generous factors: an upper bound is all the check needs.
    dlat_m = abs(lat1 - lat2) * 111_700.0
    dlon = abs((lon1 - lon2 + 180.0) % 360.0 - 180.0)
    dlon_m = dlon * 111_700.0 * math.cos(math.radians(lat1))
    return math.hypot(dlat_m, dlon_m)


def test_vincenty_reference_is_sane() -> None:
    # One degree of latitude at the equator is 110,574 m on WGS-84; one of longitude is
    # 111,319 m: published values, so the reference itself is checked.
    assert vincenty_inverse_m(0.0, 0.0, 1.0, 0.0) == pytest.approx(110_574.4, abs=0.5)
    assert vincenty_inverse_m(0.0, 0.0, 0.0, 1.0) == pytest.approx(111_319.5, abs=0.5)


@given(
    _ref_lat,
    _ref_lon,
    st.floats(min_value=0.0, max_value=50_000.0),
    _bearing,
)
def test_round_trip_xy_latlon_xy_within_1_mm(
    ref_lat: float, ref_lon: float, r: float, bearing: float
) -> None:
    proj = MercatorProjection(ref_lat, ref_lon)
    x, y = r * math.sin(bearing), r * math.cos(bearing)
    lat, lon = proj.to_latlon(x, y)
    x2, y2 = proj.to_xy(lat, lon)
    assert math.hypot(x2 - x, y2 - y) < 1e-3


@given(
    _ref_lat,
    _ref_lon,
    st.floats(min_value=-1.0, max_value=1.0),
    st.floats(min_value=-1.0, max_value=1.0),
)
def test_round_trip_latlon_xy_latlon_within_1_mm(
    ref_lat: float, ref_lon: float, north: float, east: float
) -> None:
    # Offsets scaled so the point lies within ~50 km of the reference.
    lat = ref_lat + north * 0.44
    lon = ref_lon + east * 0.44 / math.cos(math.radians(lat))
    lon = (lon + 180.0) % 360.0 - 180.0
    proj = MercatorProjection(ref_lat, ref_lon)
    lat2, lon2 = proj.to_latlon(*proj.to_xy(lat, lon))
    assert _ground_error_m(lat, lon, lat2, lon2) < 1e-3


@given(_ref_lat, _ref_lon, _bearing)
def test_metres_are_true_metres_at_10_km(ref_lat: float, ref_lon: float, bearing: float) -> None:
    proj = MercatorProjection(ref_lat, ref_lon)
    lat, lon = proj.to_latlon(10_000.0 * math.sin(bearing), 10_000.0 * math.cos(bearing))
    geodesic = vincenty_inverse_m(ref_lat, ref_lon, lat, lon)
    assert geodesic == pytest.approx(10_000.0, rel=0.005)


@given(
    _ref_lat,
    _ref_lon,
    st.tuples(st.floats(-5_000.0, 5_000.0), st.floats(-5_000.0, 5_000.0)),
    st.tuples(st.floats(-5_000.0, 5_000.0), st.floats(-5_000.0, 5_000.0)),
)
def test_planar_distances_near_reference_match_geodesic(
    ref_lat: float,
    ref_lon: float,
    p: tuple[float, float],
    q: tuple[float, float],
) -> None:
    planar = math.dist(p, q)
    if planar < 1.0:
        return  # relative error is meaningless at the rounding floor
    proj = MercatorProjection(ref_lat, ref_lon)
    geodesic = vincenty_inverse_m(*proj.to_latlon(*p), *proj.to_latlon(*q))
    assert planar == pytest.approx(geodesic, rel=0.005)


def test_scale_is_exact_at_the_reference() -> None:
    # 1 m steps at the reference are 1 m on the ellipsoid to well under 0.1 %.
    for ref_lat in (-70.0, -33.9, 0.0, 42.36, 70.0):
        proj = MercatorProjection(ref_lat, 10.0)
        for x, y in ((1.0, 0.0), (0.0, 1.0)):
            d = vincenty_inverse_m(ref_lat, 10.0, *proj.to_latlon(x, y))
            assert d == pytest.approx(1.0, rel=1e-4)


def test_reference_maps_to_origin() -> None:
    proj = MercatorProjection(42.36, -71.09)
    assert proj.to_xy(42.36, -71.09) == (0.0, 0.0)
    lat, lon = proj.to_latlon(0.0, 0.0)
    assert lat == pytest.approx(42.36, abs=1e-12)
    assert lon == pytest.approx(-71.09, abs=1e-12)


@pytest.mark.parametrize("ref_lat", [-60.0, 0.0, 42.36])
def test_east_is_plus_x_and_north_is_plus_y(ref_lat: float) -> None:
    proj = MercatorProjection(ref_lat, 20.0)
    x, y = proj.to_xy(ref_lat, 20.01)
    assert x > 0.0
    assert y == pytest.approx(0.0, abs=1e-9)
    x, y = proj.to_xy(ref_lat + 0.01, 20.0)
    assert y > 0.0
    assert x == 0.0
    x, y = proj.to_xy(ref_lat - 0.01, 19.99)
    assert x < 0.0 and y < 0.0


def test_across_the_antimeridian_stays_small() -> None:
    proj = MercatorProjection(-17.0, 179.95)
    x, y = proj.to_xy(-17.0, -179.95)  # 0.1 degree east, across the date line
    assert 10_000.0 < x < 11_000.0
    lat, lon = proj.to_latlon(x, y)
    assert lat == pytest.approx(-17.0, abs=1e-9)
    assert lon == pytest.approx(-179.95, abs=1e-9)


def test_refuses_degenerate_input() -> None:
    with pytest.raises(ValueError, match="latitude"):
        MercatorProjection(89.5, 0.0)
    with pytest.raises(ValueError, match="finite"):
        MercatorProjection(math.nan, 0.0)
    proj = MercatorProjection(0.0, 0.0)
    with pytest.raises(ValueError, match="latitude"):
        proj.to_xy(90.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        proj.to_xy(0.0, math.inf)
    with pytest.raises(ValueError, match="finite"):
        proj.to_latlon(math.nan, 0.0)
