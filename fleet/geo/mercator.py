"""Mercator projection about a reference point (thesis 2.8.1), both ways.

The thesis converted Piccolo latitude/longitude to metres for its MILP models with the
Mercator routine of its reference [7] (POSC Epicentre, "Projections and Projected
Coordinate Systems"). This is that projection on the **WGS-84 ellipsoid** (EPSG method
"Mercator (variant B)": the standard parallel is the reference latitude), shifted so that
the reference point is the origin:

    k0 = cos(phi0) / sqrt(1 - e^2 sin^2(phi0))      scale factor at the reference
    x  = a k0 (lambda - lambda0)                     metres east
    y  = a k0 (psi(phi) - psi(phi0))                 metres north
    psi(phi) = atanh(sin phi) - e atanh(e sin phi)   isometric latitude

With the standard parallel at the reference latitude the scale is exactly 1 there, so a
metre on the (x, y) plane is a true ground metre near the reference; it drifts by about
tan(phi0) * (north offset / Earth radius), e.g. 0.2 % 10 km north of a 70 degree
reference. The ellipsoid rather than a sphere matters at that level: a sphere of mean
radius is up to 0.5 % off the true north-south metre near the equator.

The projection is conformal, so headings are preserved; it is undefined at the poles.
Longitude differences are wrapped to [-180, 180) so that a reference near the
antimeridian still gives small x for nearby points.
"""

from __future__ import annotations

import math

from fleet.geo.angles import wrap_degrees

__all__ = ["WGS84_A", "WGS84_F", "MercatorProjection"]

#: WGS-84 semi-major axis (m).
WGS84_A = 6_378_137.0
#: WGS-84 flattening.
WGS84_F = 1.0 / 298.257223563
_E2 = WGS84_F * (2.0 - WGS84_F)
_E = math.sqrt(_E2)

# A reference this close to a pole makes k0 -> 0 and x, y meaningless.
_MAX_REF_LAT_DEG = 89.0
# Newton on the isometric latitude converges quadratically from the spherical guess;
# 1e-15 rad (~6 nm on the ground) is at the limit of double precision.
_INVERSE_TOL_RAD = 1e-15
_INVERSE_MAX_ITER = 10


def _isometric_latitude(phi: float) -> float:
    sin_phi = math.sin(phi)
    return math.atanh(sin_phi) - _E * math.atanh(_E * sin_phi)


class MercatorProjection:
    """Ellipsoidal (WGS-84) Mercator with its standard parallel at the reference.

    `to_xy` gives (x east, y north) in metres relative to the reference point;
    `to_latlon` inverts it. Degrees in, degrees out.
    """

    __slots__ = ("_k_a", "_psi0", "ref_lat_deg", "ref_lon_deg")

    def __init__(self, ref_lat_deg: float, ref_lon_deg: float) -> None:
        if not (math.isfinite(ref_lat_deg) and math.isfinite(ref_lon_deg)):
            raise ValueError(f"reference must be finite, got ({ref_lat_deg}, {ref_lon_deg})")
        if abs(ref_lat_deg) > _MAX_REF_LAT_DEG:
            raise ValueError(
                f"reference latitude {ref_lat_deg} is beyond +/-{_MAX_REF_LAT_DEG} degrees: "
                "Mercator degenerates near the poles"
            )
        self.ref_lat_deg = ref_lat_deg
        self.ref_lon_deg = wrap_degrees(ref_lon_deg)
        phi0 = math.radians(ref_lat_deg)
        sin_phi0 = math.sin(phi0)
        k0 = math.cos(phi0) / math.sqrt(1.0 - _E2 * sin_phi0 * sin_phi0)
        self._k_a = WGS84_A * k0
        self._psi0 = _isometric_latitude(phi0)

    def __repr__(self) -> str:
        return f"MercatorProjection({self.ref_lat_deg!r}, {self.ref_lon_deg!r})"

    def to_xy(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """(x east, y north) in metres of a point, relative to the reference."""
        if not (math.isfinite(lat_deg) and math.isfinite(lon_deg)):
            raise ValueError(f"position must be finite, got ({lat_deg}, {lon_deg})")
        if not -90.0 < lat_deg < 90.0:
            raise ValueError(f"latitude {lat_deg} is outside (-90, 90): no Mercator image")
        x = self._k_a * math.radians(wrap_degrees(lon_deg - self.ref_lon_deg))
        y = self._k_a * (_isometric_latitude(math.radians(lat_deg)) - self._psi0)
        return x, y

    def to_latlon(self, x: float, y: float) -> tuple[float, float]:
        """(latitude, longitude) in degrees of a point (x east, y north) metres from the
        reference; longitude wrapped to [-180, 180)."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"x, y must be finite, got ({x}, {y})")
        psi = y / self._k_a + self._psi0
        # The spherical inverse (Gudermannian) is within ~0.2 degrees of the answer;
        # Newton on psi(phi) = psi, with dpsi/dphi = (1 - e^2) / ((1 - e^2 sin^2) cos).
        phi = math.atan(math.sinh(psi))
        for _ in range(_INVERSE_MAX_ITER):
            sin_phi = math.sin(phi)
            w = 1.0 - _E2 * sin_phi * sin_phi
            step = (_isometric_latitude(phi) - psi) * w * math.cos(phi) / (1.0 - _E2)
            phi -= step
            if abs(step) < _INVERSE_TOL_RAD:
                break
        lon = wrap_degrees(self.ref_lon_deg + math.degrees(x / self._k_a))
        return math.degrees(phi), lon


def distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Metres between two (lat, lon) points, in the local Mercator frame of `a`.

    Exact enough for the short distances it serves (a target and an aircraft closing
    on it: the scale error is under 0.1 % within 10 km).
    """
    x, y = MercatorProjection(*a).to_xy(*b)
    return math.hypot(x, y)
