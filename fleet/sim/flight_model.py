"""The aircraft a simulated autopilot flies: a `FlightModel`, chosen by `Dynamics`.

The autopilot (`fleet.sim.autopilot`) owns the guidance, the flight plan and the link;
what it flies is a flight model stepped with the guidance's `Command` (bank, airspeed,
altitude) in the wind of the moment. Two implementations:

* `KinematicModel` (the default): the project's point dynamics (`fleet.sim.aircraft`),
  deterministic and cheap, the model the approach-time predictions are built on;
* `fleet.sim.jsbsim_model.JSBSimModel`: a third-party six-degree-of-freedom
  flight-dynamics model (JSBSim) behind simple inner loops, so a plan can be checked
  against dynamics the project did not write. Optional (`pip install '.[jsbsim]'`).

Both give the guidance the same `AircraftState` (local metres on the autopilot's Mercator
plane, the air-relative track as heading) and the telemetry its `Sensors`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Protocol

from fleet.errors import FleetError
from fleet.geo.aircraft import GRAVITY, AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.sim.aircraft import AircraftState, Command, Wind, step

__all__ = [
    "Dynamics",
    "FlightModel",
    "FlightModelError",
    "KinematicModel",
    "Sensors",
    "make_flight_model",
    "require",
]


class Dynamics(enum.StrEnum):
    """Which flight model the simulated aircraft fly."""

    KINEMATIC = "kinematic"
    JSBSIM = "jsbsim"


class FlightModelError(FleetError, RuntimeError):
    """The chosen flight model cannot run here (its package is not installed) or
    cannot start this aircraft (JSBSim did not load or trim it)."""


@dataclass(frozen=True, slots=True)
class Sensors:
    """What the autopilot's sensors read, for its telemetry (SI units, radians)."""

    vel_north: float  #: ground velocity, m/s
    vel_east: float
    vel_down: float
    roll: float
    pitch: float
    yaw: float  #: the nose's heading, clockwise from true north
    p: float  #: body rates, rad/s
    q: float
    r: float
    accel_x: float  #: specific force along the body axes, m/s^2
    accel_y: float
    accel_z: float


class FlightModel(Protocol):
    """An aircraft the autopilot can fly."""

    @property
    def state(self) -> AircraftState:
        """Where the aircraft is and how it flies, as the guidance sees it."""
        ...

    def step(self, command: Command, wind: Wind, dt: float) -> AircraftState:
        """Fly `dt` seconds under `command` in `wind` (the air mass's velocity)."""
        ...

    def sensors(self, wind: Wind) -> Sensors:
        """The sensors' readings now (`wind` is the wind the last step flew in)."""
        ...


class KinematicModel:
    """The project's point dynamics (`fleet.sim.aircraft.step`)."""

    def __init__(self, state: AircraftState, limits: AircraftLimits) -> None:
        self._state = state
        self.limits = limits

    @property
    def state(self) -> AircraftState:
        return self._state

    def step(self, command: Command, wind: Wind, dt: float) -> AircraftState:
        self._state = step(self._state, command, self.limits, wind, dt)
        return self._state

    def sensors(self, wind: Wind) -> Sensors:
        state = self._state
        north, east = state.ground_velocity(wind)
        heading_rate = state.heading_rate
        return Sensors(
            vel_north=north,
            vel_east=east,
            vel_down=-state.climb_rate,
            roll=state.bank,
            # The model flies at zero angle of attack: the pitch is the flight-path angle.
            pitch=state.pitch,
            yaw=state.heading,
            p=state.roll_rate,
            q=heading_rate * math.sin(state.bank),
            r=heading_rate * math.cos(state.bank),
            accel_x=state.acceleration,
            accel_y=0.0,
            # Specific force of level coordinated flight: the load factor, body down.
            accel_z=-GRAVITY / math.cos(state.bank),
        )


def make_flight_model(
    dynamics: Dynamics,
    start: AircraftState,
    limits: AircraftLimits,
    projection: MercatorProjection,
    wind: Wind,
) -> FlightModel:
    """The flight model `dynamics` names, flying from `start` (whose x, y are on
    `projection`'s plane) in `wind`. Raises FlightModelError when JSBSim is
    asked for but not installed or cannot start the aircraft, ValueError when the start
    airspeed is outside what the model flies."""
    if dynamics is Dynamics.KINEMATIC:
        return KinematicModel(start, limits)
    require(dynamics)
    from fleet.sim.jsbsim_model import JSBSimModel

    return JSBSimModel(start, limits, projection, wind)


def require(dynamics: Dynamics) -> None:
    """Raise FlightModelError, saying how to install it, if `dynamics` cannot run here."""
    if dynamics is Dynamics.KINEMATIC:
        return
    try:
        import jsbsim  # noqa: F401  (only whether it imports)
    except ImportError as error:
        raise FlightModelError(
            f"--dynamics jsbsim needs the JSBSim package, which does not import here "
            f"({error}); install it with: pip install 'uav-fleet[jsbsim]'"
        ) from error
