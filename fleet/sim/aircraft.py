"""Point dynamics of a fixed-wing aircraft in coordinated flight, pure (no I/O, no clock).

The model is what a Piccolo's inner loops make of an aircraft, seen from outside:

* true airspeed follows its command at a bounded rate and stays within the airframe's
  envelope (15-30 m/s by default);
* bank follows its command at a bounded roll rate and never exceeds the bank limit
  (30 degrees by default); turns are coordinated, so the heading turns at
  ``g tan(bank) / airspeed`` and a steady turn has radius ``v^2 / (g tan(bank))``;
* altitude is held by a proportional climb command clipped to the climb-rate limit;
* the air mass moves with a constant wind (north, east), which the ground track adds.

Positions are local metres: ``x`` east, ``y`` north (the simulator's Mercator plane).
Headings are radians clockwise from true north, of the aircraft's nose, which in
coordinated flight without sideslip is the direction of its air-relative velocity.

The integration step is fixed by the caller (the simulator uses 20 ms). The position is
advanced along the heading at the middle of the step, which is exact in direction for a
constant turn rate: plain Euler would spiral outwards by about 2 % a revolution at
20 ms, enough to spoil a turn-radius check.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fleet.geo.aircraft import GRAVITY, AircraftLimits
from fleet.geo.angles import wrap_two_pi

__all__ = ["CALM", "AircraftState", "Command", "Wind", "step"]


@dataclass(frozen=True, slots=True)
class Wind:
    """A constant wind: the velocity of the air mass over the ground (the way it blows *to*)."""

    north: float = 0.0  #: m/s
    east: float = 0.0  #: m/s

    @property
    def speed(self) -> float:
        return math.hypot(self.north, self.east)


CALM = Wind()


@dataclass(frozen=True, slots=True)
class AircraftState:
    """Where the aircraft is and how it is flying."""

    x: float  #: metres east
    y: float  #: metres north
    alt: float  #: metres
    heading: float  #: radians clockwise from true north, in [0, 2 pi)
    airspeed: float  #: true airspeed, m/s
    bank: float = 0.0  #: radians, positive right wing down (turning right)
    climb_rate: float = 0.0  #: m/s, positive up
    roll_rate: float = 0.0  #: rad/s over the last step
    acceleration: float = 0.0  #: m/s^2 along the flight path over the last step

    @property
    def heading_rate(self) -> float:
        """rad/s of a coordinated turn at this bank and airspeed."""
        return GRAVITY * math.tan(self.bank) / self.airspeed

    @property
    def pitch(self) -> float:
        """The flight-path angle (radians): the model flies at zero angle of attack."""
        return math.asin(max(-1.0, min(1.0, self.climb_rate / self.airspeed)))

    def horizontal_airspeed(self) -> float:
        return math.sqrt(max(self.airspeed * self.airspeed - self.climb_rate**2, 0.0))

    def ground_velocity(self, wind: Wind = CALM) -> tuple[float, float]:
        """(north, east) ground velocity in m/s: air-relative velocity plus the wind."""
        horizontal = self.horizontal_airspeed()
        return (
            horizontal * math.cos(self.heading) + wind.north,
            horizontal * math.sin(self.heading) + wind.east,
        )


@dataclass(frozen=True, slots=True)
class Command:
    """What the guidance asks of the inner loops; out-of-envelope values are clipped."""

    bank: float  #: radians
    airspeed: float  #: m/s
    altitude: float  #: metres


def _limit(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


def step(
    state: AircraftState,
    command: Command,
    limits: AircraftLimits,
    wind: Wind,
    dt: float,
) -> AircraftState:
    """Advance the aircraft by `dt` seconds under `command`."""
    speed_change = _limit(
        limits.clamp_airspeed(command.airspeed) - state.airspeed,
        -limits.airspeed_rate * dt,
        limits.airspeed_rate * dt,
    )
    airspeed = state.airspeed + speed_change

    bank_limit = limits.bank_limit
    max_roll = math.radians(limits.roll_rate_deg) * dt
    roll = _limit(_limit(command.bank, -bank_limit, bank_limit) - state.bank, -max_roll, max_roll)
    bank = state.bank + roll

    climb = _limit(
        limits.altitude_gain * (command.altitude - state.alt), -limits.climb_rate, limits.climb_rate
    )
    # The climb can never exceed the airspeed: the flight-path angle stays below 90 degrees.
    climb = _limit(climb, -0.5 * airspeed, 0.5 * airspeed)

    heading_rate = GRAVITY * math.tan(bank) / airspeed
    mid_heading = state.heading + 0.5 * heading_rate * dt
    horizontal = math.sqrt(airspeed * airspeed - climb * climb)
    return AircraftState(
        x=state.x + (horizontal * math.sin(mid_heading) + wind.east) * dt,
        y=state.y + (horizontal * math.cos(mid_heading) + wind.north) * dt,
        alt=state.alt + climb * dt,
        heading=wrap_two_pi(state.heading + heading_rate * dt),
        airspeed=airspeed,
        bank=bank,
        climb_rate=climb,
        roll_rate=roll / dt,
        acceleration=speed_change / dt,
    )
