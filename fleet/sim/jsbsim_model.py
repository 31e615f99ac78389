"""A simulated aircraft flown on JSBSim, the open-source six-degree-of-freedom
flight-dynamics model, behind the inner loops a Piccolo closes (optional:
``pip install '.[jsbsim]'``).

The airframe is JSBSim's shipped Piper J-3 Cub (`J3Cub`): a light, slow high-wing
aircraft that cruises comfortably at a small UAV's 20-28 m/s (it stalls near 17 m/s at
1 g, 18 m/s in a 30-degree bank). It starts trimmed for level flight at the scenario's
airspeed and heading, engine running.

The guidance (`fleet.sim.guidance`) is the kinematic model's, unchanged; its `Command`
(bank, airspeed, altitude) is flown by four loops on JSBSim's normalised controls, run
at every JSBSim step (`JSBSIM_DT`):

* **bank**: the bank reference follows the command at most at the roll-rate limit and
  within the bank limit; aileron = proportional on its error, damped by the roll rate,
  with a small integral for the trim;
* **altitude**: the climb command is the kinematic model's (`altitude_gain` times the
  error, within +-`climb_rate`); a proportional-integral loop on the climb rate gives
  the pitch reference (the integral finds the angle of attack, and the extra lift a
  banked turn needs); elevator = proportional on the pitch error, damped by the pitch
  rate;
* **airspeed**: throttle = the trimmed throttle plus proportional-integral on the true
  airspeed's error;
* **coordination**: rudder = proportional-integral against the sideslip.

Wind is JSBSim's own (`atmosphere/wind-north-fps` and so on), set at every step to the
scenario's weather of that instant. `run_ic()` and the trim reset JSBSim's wind to calm,
so the model trims in calm air, then starts again (a second `run_ic`) with a ground
velocity of the trimmed air velocity plus the wind and sets the wind after it: the
aircraft starts in trimmed flight relative to the air mass, as the kinematic model does.

Everything the guidance and the telemetry see is JSBSim's state: the position (its
geodetic latitude and longitude, on the autopilot's own WGS-84 Mercator plane), the
ground velocity, the attitude, body rates and accelerations. The state's `heading` is
the direction of the air-relative velocity (what the guidance steers), the telemetry's
yaw the nose's (they differ by the sideslip).
"""

from __future__ import annotations

import logging
import math

import jsbsim

from fleet.geo.aircraft import GRAVITY, AircraftLimits
from fleet.geo.angles import wrap_two_pi
from fleet.geo.mercator import MercatorProjection
from fleet.sim.aircraft import AircraftState, Command, Wind
from fleet.sim.flight_model import FlightModelError, Sensors

__all__ = ["AIRCRAFT", "AIRSPEED_RANGE", "JSBSIM_DT", "JSBSimModel"]

logger = logging.getLogger(__name__)

#: The JSBSim airframe flown (shipped with the JSBSim package).
AIRCRAFT = "J3Cub"
#: True airspeeds (m/s) the J3Cub flies safely under these loops: above its stall in a
#: 30-degree bank, below its cruise. Commands are held within it.
AIRSPEED_RANGE = (20.0, 35.0)
#: JSBSim's integration step (s): its default rate is 120 Hz; 100 Hz divides the
#: simulator's 20 ms step.
JSBSIM_DT = 0.01

_FOOT = 0.3048

# Loop gains, tuned on the J3Cub at 20-28 m/s (tests/sim/test_jsbsim_model.py).
_ROLL_RATE_PER_RAD = 4.0  # roll rate asked (rad/s) per radian of bank error
_ROLL_RATE_PER_AILERON = 0.034  # the J3Cub's steady roll rate (rad/s) per aileron per m/s
_AILERON_PER_ROLL_RATE = 2.0  # aileron per rad/s of roll-rate error
_AILERON_INTEGRAL = 1.0  # aileron per radian-second of bank error
_PITCH_PER_CLIMB = 0.08  # radians of pitch reference per m/s of climb error
_PITCH_INTEGRAL = 0.04  # radians per (m/s)-second
_ELEVATOR_PER_RAD = 3.0  # elevator (positive: nose down) per radian of pitch error
_ELEVATOR_PER_PITCH_RATE = 1.0  # elevator per rad/s of pitch rate
_THROTTLE_PER_SPEED = 0.2  # throttle per m/s of airspeed error
_THROTTLE_INTEGRAL = 0.06  # throttle per (m/s)-second
_RUDDER_PER_RAD = 2.0  # rudder (positive: yaw left) per radian of sideslip
_RUDDER_INTEGRAL = 1.0  # rudder per radian-second of sideslip
_RUDDER_PER_AILERON = 0.3  # rudder against the aileron's adverse yaw
_RUDDER_PER_YAW_RATE = 1.0  # rudder per rad/s of yaw rate beyond a coordinated turn's
# What each integral may add (in its output's units): enough for a steady limit turn,
# not so much that it winds up while the output saturates.
_AILERON_INTEGRAL_LIMIT = 0.5
_PITCH_INTEGRAL_LIMIT = math.radians(10.0)
_THROTTLE_INTEGRAL_LIMIT = 0.6
_RUDDER_INTEGRAL_LIMIT = 0.3


def _clip(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


def _integrate(integral: float, increment: float, limit: float) -> float:
    """An integral term (in its output's units) moved on, held within +-limit."""
    return _clip(integral + increment, -limit, limit)


class JSBSimModel:
    """One aircraft on its own JSBSim instance (`fleet.sim.flight_model.FlightModel`)."""

    def __init__(
        self,
        start: AircraftState,
        limits: AircraftLimits,
        projection: MercatorProjection,
        wind: Wind,
    ) -> None:
        low, high = AIRSPEED_RANGE
        if not low <= start.airspeed <= high:
            raise ValueError(
                f"the JSBSim {AIRCRAFT} flies at {low:g}-{high:g} m/s; "
                f"a start airspeed of {start.airspeed:g} m/s is outside it"
            )
        self.limits = limits
        self.projection = projection
        # Silence: JSBSim prints a banner and its messages on stdout, which `fleet sim`
        # keeps for the lines its launcher reads.
        jsbsim.FGJSBBase().debug_lvl = 0
        fdm = jsbsim.FGFDMExec(None)  # the aircraft shipped with the package
        fdm.set_debug_level(0)
        if not fdm.load_model(AIRCRAFT):
            raise FlightModelError(f"JSBSim could not load its {AIRCRAFT} model")
        fdm.set_dt(JSBSIM_DT)
        self._fdm = fdm
        lat, lon = projection.to_latlon(start.x, start.y)
        fdm["ic/lat-geod-deg"] = lat
        fdm["ic/long-gc-deg"] = lon
        fdm["ic/h-sl-ft"] = start.alt / _FOOT
        fdm["ic/psi-true-deg"] = math.degrees(start.heading)
        fdm["ic/vt-fps"] = start.airspeed / _FOOT
        fdm["ic/gamma-deg"] = 0.0
        if not fdm.run_ic():
            raise FlightModelError("JSBSim refused the initial conditions")
        fdm["propulsion/set-running"] = -1  # every engine
        try:
            fdm["simulation/do_simple_trim"] = 1  # full longitudinal and lateral trim
        except Exception as error:  # JSBSim raises its own TrimFailureError
            raise FlightModelError(
                f"JSBSim could not trim the {AIRCRAFT} at {start.airspeed:g} m/s: {error}"
            ) from error
        self._throttle_trim = float(fdm["fcs/throttle-cmd-norm"])
        theta = float(fdm["attitude/theta-deg"])
        # Start again from the trimmed attitude, moving with the air mass (module doc).
        fdm["ic/theta-deg"] = theta
        fdm["ic/phi-deg"] = 0.0
        fdm["ic/vn-fps"] = (start.airspeed * math.cos(start.heading) + wind.north) / _FOOT
        fdm["ic/ve-fps"] = (start.airspeed * math.sin(start.heading) + wind.east) / _FOOT
        fdm["ic/vd-fps"] = 0.0
        if not fdm.run_ic():
            raise FlightModelError("JSBSim refused the trimmed initial conditions")
        self._set_wind(wind)
        self._pitch_reference = math.radians(theta)
        self._bank_reference = 0.0
        self._aileron_integral = 0.0
        self._pitch_integral = 0.0
        self._throttle_integral = 0.0
        self._rudder_integral = 0.0
        self._airspeed = start.airspeed
        self._acceleration = 0.0
        self._state = self._read_state()

    def _set_wind(self, wind: Wind) -> None:
        fdm = self._fdm
        fdm["atmosphere/wind-north-fps"] = wind.north / _FOOT
        fdm["atmosphere/wind-east-fps"] = wind.east / _FOOT
        fdm["atmosphere/wind-down-fps"] = 0.0

    @property
    def state(self) -> AircraftState:
        return self._state

    @property
    def fdm(self) -> jsbsim.FGFDMExec:
        """The JSBSim instance (read its properties; do not step it)."""
        return self._fdm

    def step(self, command: Command, wind: Wind, dt: float) -> AircraftState:
        self._set_wind(wind)
        substeps = max(1, round(dt / JSBSIM_DT))
        before = self._airspeed
        for _ in range(substeps):
            self._control(command, JSBSIM_DT)
            self._fdm.run()
        self._state = self._read_state()
        self._acceleration = (self._state.airspeed - before) / (substeps * JSBSIM_DT)
        self._airspeed = self._state.airspeed
        self._state = _with_acceleration(self._state, self._acceleration)
        return self._state

    def _control(self, command: Command, dt: float) -> None:
        """One step of the four inner loops (module docstring)."""
        fdm = self._fdm
        limits = self.limits
        bank = float(fdm["attitude/phi-rad"])
        pitch = float(fdm["attitude/theta-rad"])
        airspeed = float(fdm["velocities/vtrue-fps"]) * _FOOT
        climb = float(fdm["velocities/h-dot-fps"]) * _FOOT
        altitude = float(fdm["position/h-sl-meters"])
        sideslip = float(fdm["aero/beta-rad"])

        # Bank: the reference moves toward the command at the roll-rate limit; a roll
        # rate toward it is asked of the aileron, fed forward through the airframe's
        # roll rate per aileron, with an integral for the aileron a steady turn needs.
        target = _clip(command.bank, -limits.bank_limit, limits.bank_limit)
        max_roll = math.radians(limits.roll_rate_deg) * dt
        reference_rate = _clip(target - self._bank_reference, -max_roll, max_roll) / dt
        self._bank_reference += reference_rate * dt
        bank_error = self._bank_reference - bank
        roll_rate_command = reference_rate + _ROLL_RATE_PER_RAD * bank_error
        self._aileron_integral = _integrate(
            self._aileron_integral, _AILERON_INTEGRAL * bank_error * dt, _AILERON_INTEGRAL_LIMIT
        )
        aileron = _clip(
            roll_rate_command / (_ROLL_RATE_PER_AILERON * max(airspeed, 1.0))
            + _AILERON_PER_ROLL_RATE * (roll_rate_command - float(fdm["velocities/p-rad_sec"]))
            + self._aileron_integral,
            -1.0,
            1.0,
        )
        fdm["fcs/aileron-cmd-norm"] = aileron

        # Altitude through the climb rate, the pitch and the elevator.
        climb_command = _clip(
            limits.altitude_gain * (command.altitude - altitude),
            -limits.climb_rate,
            limits.climb_rate,
        )
        climb_error = climb_command - climb
        self._pitch_integral = _integrate(
            self._pitch_integral, _PITCH_INTEGRAL * climb_error * dt, _PITCH_INTEGRAL_LIMIT
        )
        pitch_reference = _clip(
            self._pitch_reference + _PITCH_PER_CLIMB * climb_error + self._pitch_integral,
            math.radians(-15.0),
            math.radians(20.0),
        )
        fdm["fcs/elevator-cmd-norm"] = _clip(
            -_ELEVATOR_PER_RAD * (pitch_reference - pitch)
            + _ELEVATOR_PER_PITCH_RATE * float(fdm["velocities/q-rad_sec"]),
            -1.0,
            1.0,
        )

        # Airspeed through the throttle.
        low, high = AIRSPEED_RANGE
        speed_command = _clip(limits.clamp_airspeed(command.airspeed), low, high)
        speed_error = speed_command - airspeed
        self._throttle_integral = _integrate(
            self._throttle_integral, _THROTTLE_INTEGRAL * speed_error * dt, _THROTTLE_INTEGRAL_LIMIT
        )
        fdm["fcs/throttle-cmd-norm"] = _clip(
            self._throttle_trim + _THROTTLE_PER_SPEED * speed_error + self._throttle_integral,
            0.0,
            1.0,
        )

        # Coordination: the rudder follows the aileron (against its adverse yaw), damps
        # the yaw rate's departure from a coordinated turn's, and cancels the sideslip.
        coordinated_yaw_rate = GRAVITY * math.sin(bank) * math.cos(pitch) / max(airspeed, 1.0)
        yaw_rate_error = float(fdm["velocities/r-rad_sec"]) - coordinated_yaw_rate
        self._rudder_integral = _integrate(
            self._rudder_integral, -_RUDDER_INTEGRAL * sideslip * dt, _RUDDER_INTEGRAL_LIMIT
        )
        fdm["fcs/rudder-cmd-norm"] = _clip(
            -_RUDDER_PER_AILERON * aileron
            - _RUDDER_PER_RAD * sideslip
            + _RUDDER_PER_YAW_RATE * yaw_rate_error
            + self._rudder_integral,
            -1.0,
            1.0,
        )

    def _read_state(self) -> AircraftState:
        fdm = self._fdm
        x, y = self.projection.to_xy(
            float(fdm["position/lat-geod-deg"]), float(fdm["position/long-gc-deg"])
        )
        air_north = float(fdm["velocities/v-north-fps"]) - float(fdm["atmosphere/wind-north-fps"])
        air_east = float(fdm["velocities/v-east-fps"]) - float(fdm["atmosphere/wind-east-fps"])
        return AircraftState(
            x=x,
            y=y,
            alt=float(fdm["position/h-sl-meters"]),
            heading=wrap_two_pi(math.atan2(air_east, air_north)),
            airspeed=float(fdm["velocities/vtrue-fps"]) * _FOOT,
            bank=float(fdm["attitude/phi-rad"]),
            climb_rate=float(fdm["velocities/h-dot-fps"]) * _FOOT,
            roll_rate=float(fdm["velocities/p-rad_sec"]),
        )

    def sensors(self, wind: Wind) -> Sensors:
        fdm = self._fdm
        return Sensors(
            vel_north=float(fdm["velocities/v-north-fps"]) * _FOOT,
            vel_east=float(fdm["velocities/v-east-fps"]) * _FOOT,
            vel_down=float(fdm["velocities/v-down-fps"]) * _FOOT,
            roll=float(fdm["attitude/phi-rad"]),
            pitch=float(fdm["attitude/theta-rad"]),
            yaw=float(fdm["attitude/psi-rad"]),
            p=float(fdm["velocities/p-rad_sec"]),
            q=float(fdm["velocities/q-rad_sec"]),
            r=float(fdm["velocities/r-rad_sec"]),
            accel_x=float(fdm["accelerations/a-pilot-x-ft_sec2"]) * _FOOT,
            accel_y=float(fdm["accelerations/a-pilot-y-ft_sec2"]) * _FOOT,
            accel_z=float(fdm["accelerations/a-pilot-z-ft_sec2"]) * _FOOT,
        )


def _with_acceleration(state: AircraftState, acceleration: float) -> AircraftState:
    return AircraftState(
        x=state.x,
        y=state.y,
        alt=state.alt,
        heading=state.heading,
        airspeed=state.airspeed,
        bank=state.bank,
        climb_rate=state.climb_rate,
        roll_rate=state.roll_rate,
        acceleration=acceleration,
    )
