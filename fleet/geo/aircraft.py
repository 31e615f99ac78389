"""The fixed-wing aircraft's flight envelope and the geometry of a coordinated turn.

One `AircraftLimits` serves the simulator (which flies the aircraft inside it) and the
onboard approach-time model (which predicts how fast the aircraft can reach a point):
both must agree on the same envelope, or the prediction would not match the flight.

Angles at this interface are in degrees (`bank_limit_deg`, `turn_radius`'s bank), the
unit of the scenario files and of the operator; `AircraftLimits.bank_limit` gives
radians for the dynamics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["GRAVITY", "AircraftLimits", "turn_radius"]

GRAVITY = 9.80665
"""Standard gravity, m/s^2."""


def turn_radius(speed: float, bank_deg: float) -> float:
    """Radius in metres of a steady coordinated level turn at `speed` (m/s, air-relative).

    r = v^2 / (g tan|bank|); a zero bank means the aircraft does not turn, which is
    reported as an infinite radius.
    """
    tan_bank = math.tan(math.radians(abs(bank_deg)))
    if tan_bank <= 0.0:
        return math.inf
    return speed * speed / (GRAVITY * tan_bank)


@dataclass(frozen=True, slots=True)
class AircraftLimits:
    """The flight envelope and the response of the inner loops, SI units."""

    min_airspeed: float = 15.0  #: m/s, true airspeed
    max_airspeed: float = 30.0  #: m/s
    airspeed_rate: float = 1.0  #: m/s^2, how fast the airspeed follows its command
    bank_limit_deg: float = 30.0  #: degrees
    roll_rate_deg: float = 45.0  #: degrees per second
    climb_rate: float = 3.0  #: m/s, the limit both up and down
    altitude_gain: float = 0.25  #: 1/s, climb command per metre of altitude error

    def __post_init__(self) -> None:
        # A fixed-wing aircraft always flies and always can turn: the approach model
        # divides by the airspeed and needs a positive lateral acceleration.
        if not 0.0 < self.min_airspeed <= self.max_airspeed < math.inf:
            raise ValueError(
                f"airspeed limits must satisfy 0 < min <= max < inf, got "
                f"{self.min_airspeed}, {self.max_airspeed}"
            )
        if not 0.0 < self.bank_limit_deg < 90.0:
            raise ValueError(f"bank limit must be in (0, 90) degrees, got {self.bank_limit_deg}")
        for name in ("airspeed_rate", "roll_rate_deg", "climb_rate", "altitude_gain"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a positive number, got {value}")

    @property
    def bank_limit(self) -> float:
        """The bank limit in radians."""
        return math.radians(self.bank_limit_deg)

    @property
    def max_accel(self) -> float:
        """Lateral acceleration of a coordinated turn at the bank limit, m/s^2."""
        return GRAVITY * math.tan(self.bank_limit)

    def clamp_airspeed(self, airspeed: float) -> float:
        """The airspeed the aircraft can actually be flying at."""
        return min(max(airspeed, self.min_airspeed), self.max_airspeed)

    def turn_radius(self, airspeed: float) -> float:
        """Radius (m) of a turn at the bank limit at `airspeed`."""
        return turn_radius(airspeed, self.bank_limit_deg)
