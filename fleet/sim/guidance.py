"""Lateral and vertical guidance toward the tracked waypoint, pure.

The law is *course pursuit*: the ground course (direction of the ground velocity, so the
wind is compensated without being estimated) is steered toward the bearing of the
waypoint, with a commanded turn rate proportional to the course error,

    turn rate = course_gain * course error,   bank = atan(turn rate * airspeed / g),

clipped to the bank limit. A large error therefore turns at the bank limit and a small
one decays with a time constant 1 / course_gain (2.5 s). The resulting path to a point
is a minimum-radius turn toward it followed by a straight line: the time-optimal (Dubins)
path to a point outside the turning circle, the path an approach-time model predicts.

In wind, a waypoint behind is turned to on the side the air mass favours (see
`_turn_side_in_wind`); after the turn the course law above takes over.

One case would defeat pure pursuit: a waypoint *inside* the circle the aircraft would
turn on. Turning toward it forever orbits it without coming closer. So when the waypoint
lies deeper inside that circle than half the acceptance radius, the aircraft flies
wings level until the waypoint is far enough out, then turns; the turn then passes
within half the acceptance radius of the waypoint, so the waypoint is always reached.

A waypoint is reached when the aircraft is within the acceptance radius of it
(horizontal distance; 60 m by default).

`fly_to_point` runs this guidance and the aircraft model of `fleet.sim.aircraft`, the
very code the simulator steps, from a state to a point, and returns the arrival time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypedDict, Unpack

from fleet.errors import FleetError
from fleet.geo.aircraft import GRAVITY, AircraftLimits, turn_radius
from fleet.geo.angles import wrap_pi
from fleet.sim.aircraft import CALM, AircraftState, Command, Wind, step

#: Simulated integration step of the simulator (s).
STEP_S = 0.02
#: Default acceptance radius (m).
DEFAULT_ACCEPTANCE_RADIUS = 60.0
# Below this ground speed (m/s) the ground course is meaningless (a wind nearly as fast
# as the aircraft); the heading stands in for it.
_MIN_GROUND_SPEED = 1.0


@dataclass(frozen=True, slots=True)
class GuidanceSettings:
    course_gain: float = 0.4  #: 1/s: commanded turn rate per radian of course error
    acceptance_radius: float = DEFAULT_ACCEPTANCE_RADIUS  #: metres

    def __post_init__(self) -> None:
        if not (math.isfinite(self.course_gain) and self.course_gain > 0.0):
            raise ValueError(f"course gain must be positive, got {self.course_gain}")
        if not (math.isfinite(self.acceptance_radius) and self.acceptance_radius > 0.0):
            raise ValueError(f"acceptance radius must be positive, got {self.acceptance_radius}")


DEFAULT_GUIDANCE = GuidanceSettings()


class UnreachedError(FleetError, RuntimeError):
    """The aircraft did not reach the point within the time allowed."""


def distance_to(state: AircraftState, target_xy: tuple[float, float]) -> float:
    return math.hypot(target_xy[0] - state.x, target_xy[1] - state.y)


def has_arrived(
    state: AircraftState,
    target_xy: tuple[float, float],
    settings: GuidanceSettings = DEFAULT_GUIDANCE,
) -> bool:
    return distance_to(state, target_xy) <= settings.acceptance_radius


def bank_command(
    state: AircraftState,
    target_xy: tuple[float, float],
    limits: AircraftLimits,
    wind: Wind = CALM,
    settings: GuidanceSettings = DEFAULT_GUIDANCE,
) -> float:
    """The bank (radians) that steers the ground course toward `target_xy`."""
    dx = target_xy[0] - state.x
    dy = target_xy[1] - state.y
    north, east = state.ground_velocity(wind)
    ground_speed = math.hypot(north, east)
    course = math.atan2(east, north) if ground_speed >= _MIN_GROUND_SPEED else state.heading
    error = wrap_pi(math.atan2(dx, dy) - course)
    if abs(error) > 0.5 * math.pi and (wind.north or wind.east):
        error = _turn_side_in_wind(state, dx, dy, wind, error)

    bank_limit = limits.bank_limit
    # The circle a limit turn toward the waypoint would fly. Its radius is taken at the
    # larger of air and ground speed: in wind the ground track of a turn is stretched
    # downwind, and a circle too large only costs a little straight flight.
    speed = max(state.airspeed, ground_speed)
    radius = turn_radius(speed, limits.bank_limit_deg)
    side = 1.0 if error >= 0.0 else -1.0
    centre_x = state.x + side * radius * math.cos(course)
    centre_y = state.y - side * radius * math.sin(course)
    if math.hypot(target_xy[0] - centre_x, target_xy[1] - centre_y) < (
        radius - 0.5 * settings.acceptance_radius
    ):
        return 0.0

    turn_rate = settings.course_gain * error
    bank = math.atan(turn_rate * state.airspeed / GRAVITY)
    return max(-bank_limit, min(bank_limit, bank))


def _turn_side_in_wind(
    state: AircraftState, dx: float, dy: float, wind: Wind, error: float
) -> float:
    """The course error to turn by, for a waypoint behind: the side is the air mass's.

    Turning toward the waypoint's bearing over the ground would turn a crabbed aircraft
    downwind for a waypoint nearly astern, the slow way (up to 20 % longer at 1 km in a
    10 m/s crosswind). Seen from the air the waypoint drifts against the wind, so the
    turn goes toward where it will be then, relative to the heading: the side of the
    time-optimal (Dubins) path in the wind. In calm air this is the course's own side.
    """
    lead = math.hypot(dx, dy) / state.airspeed
    ahead = wrap_pi(math.atan2(dx - wind.east * lead, dy - wind.north * lead) - state.heading)
    return error if ahead * error >= 0.0 else math.copysign(abs(error), ahead)


def command_toward(
    state: AircraftState,
    target_xy: tuple[float, float],
    target_alt: float,
    airspeed: float,
    limits: AircraftLimits,
    wind: Wind = CALM,
    settings: GuidanceSettings = DEFAULT_GUIDANCE,
) -> Command:
    """Full command toward a waypoint: bank from the course law, its altitude, `airspeed`."""
    return Command(
        bank=bank_command(state, target_xy, limits, wind, settings),
        airspeed=airspeed,
        altitude=target_alt,
    )


def fly_until_arrival(
    state: AircraftState,
    target_xy: tuple[float, float],
    *,
    limits: AircraftLimits | None = None,
    wind: Wind = CALM,
    airspeed: float | None = None,
    altitude: float | None = None,
    acceptance_radius: float = DEFAULT_ACCEPTANCE_RADIUS,
    max_time: float = 3600.0,
    dt: float = STEP_S,
) -> tuple[float, AircraftState]:
    """Fly from `state` to `target_xy`; return (arrival time in s, state on arrival).

    Arrival is the first step at which the aircraft is within `acceptance_radius` of the
    point, the moment the simulator would switch to the next waypoint. `airspeed` and
    `altitude` default to the state's. Raises UnreachedError after `max_time` seconds.
    """
    limits = AircraftLimits() if limits is None else limits
    settings = GuidanceSettings(acceptance_radius=acceptance_radius)
    command_airspeed = state.airspeed if airspeed is None else airspeed
    command_altitude = state.alt if altitude is None else altitude
    if not (math.isfinite(max_time) and max_time >= 0.0 and dt > 0.0):
        raise ValueError(f"max_time must be finite and >= 0 and dt > 0, got {max_time}, {dt}")
    steps = math.ceil(max_time / dt)
    for count in range(steps + 1):
        if has_arrived(state, target_xy, settings):
            return count * dt, state
        if count == steps:
            break
        command = command_toward(
            state, target_xy, command_altitude, command_airspeed, limits, wind, settings
        )
        state = step(state, command, limits, wind, dt)
    raise UnreachedError(
        f"not within {acceptance_radius} m of {target_xy} after {max_time} s "
        f"(still {distance_to(state, target_xy):.0f} m away)"
    )


class FlightOptions(TypedDict, total=False):
    """The keyword options of `fly_until_arrival`, which holds their defaults."""

    limits: AircraftLimits | None
    wind: Wind
    airspeed: float | None
    altitude: float | None
    acceptance_radius: float
    max_time: float
    dt: float


def fly_to_point(
    state: AircraftState, target_xy: tuple[float, float], **options: Unpack[FlightOptions]
) -> float:
    """Seconds the simulated aircraft takes from `state` to within `acceptance_radius`
    of `target_xy` (local metres, x east, y north). See `fly_until_arrival`."""
    arrival, _ = fly_until_arrival(state, target_xy, **options)
    return arrival
