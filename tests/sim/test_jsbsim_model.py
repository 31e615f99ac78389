"""The JSBSim flight model (`--dynamics jsbsim`): JSBSim's J3Cub behind the simulated
autopilot's guidance. It reaches a waypoint in about the time the kinematic model takes
(the two differ in the turns' entries and exits), holds its airspeed and altitude,
drifts with JSBSim's own wind, and its telemetry is JSBSim's state.

All in simulated time, in this process (JSBSim is a library): no wall clock.
"""

from __future__ import annotations

import argparse
import math
import sys

import pytest

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.launch.up_command import add_up_parser, up_options
from fleet.sim.aircraft import AircraftState, Command, Wind
from fleet.sim.autopilot import STEP_MS, AutopilotSettings, SimulatedAutopilot
from fleet.sim.flight_model import Dynamics, FlightModelError, require
from fleet.sim.guidance import fly_to_point
from fleet.sim.uav_spec import UavSpec
from fleet.transport.cli import ExitCode
from programs import fleet_cli

REFERENCE = (35.72, -120.765)
#: Two waypoints: 1.4 km ahead and 45 degrees right of a UAV flying north, then back
#: behind it (a turn of more than 120 degrees).
PLAN_XY = ((1000.0, 1000.0), (-1500.0, -500.0))
AIRSPEED = 22.0


def _uav(airspeed: float = AIRSPEED) -> UavSpec:
    projection = MercatorProjection(*REFERENCE)
    plan = tuple((*projection.to_latlon(x, y), 600.0) for x, y in PLAN_XY)
    return UavSpec(7, *REFERENCE, alt=600.0, heading=0.0, airspeed=airspeed, plan=plan)


def _jsbsim() -> None:
    pytest.importorskip("jsbsim", reason="JSBSim is not installed: pip install '.[jsbsim]'")


def _fly_to_first_waypoint(
    wind: Wind, dynamics: Dynamics
) -> tuple[float, SimulatedAutopilot, list[AircraftState]]:
    """Seconds until the autopilot reports waypoint 0 reached, the autopilot, the states."""
    autopilot = SimulatedAutopilot(_uav(), AutopilotSettings(wind=wind, dynamics=dynamics))
    states = []
    while autopilot.counters["arrivals"] == 0:
        autopilot.step()
        states.append(autopilot.state)
        assert autopilot.time_ms < 600_000, "waypoint 0 not reached in 10 simulated minutes"
    return autopilot.time_ms / 1000.0, autopilot, states


@pytest.mark.parametrize(
    "wind",
    [Wind(), Wind(east=10.0), Wind(north=-8.0, east=3.0)],
    ids=["calm", "10 m/s westerly", "9 m/s from the north-north-west"],
)
def test_flies_to_a_waypoint_as_the_kinematic_model_does_holding_airspeed(wind: Wind) -> None:
    _jsbsim()
    flown, autopilot, states = _fly_to_first_waypoint(wind, Dynamics.JSBSIM)
    # Reached truthfully: JSBSim's own position within the acceptance radius.
    target = PLAN_XY[0]
    arrived = autopilot.state
    assert math.dist((arrived.x, arrived.y), target) <= autopilot.guidance.acceptance_radius
    assert autopilot.tracked == 1
    # The same guidance on the kinematic model: the times agree within 2 %.
    kinematic, _, _ = _fly_to_first_waypoint(wind, Dynamics.KINEMATIC)
    assert abs(flown - kinematic) <= 0.02 * kinematic, (flown, kinematic)
    # The inner loops hold the commanded airspeed and the altitude, turns included.
    assert max(abs(s.airspeed - AIRSPEED) for s in states) < 1.5
    assert max(abs(s.alt - 600.0) for s in states) < 6.0
    # and the bank stays near the limit (30 degrees): a brief overshoot at most.
    assert max(abs(s.bank) for s in states) < math.radians(34.0)


def test_drifts_with_the_wind_at_its_airspeed() -> None:
    """Wings level, heading north, for 60 s in an 8 m/s wind blowing east: the ground
    track drifts 8 m/s east while the aircraft holds 22 m/s through the air."""
    _jsbsim()
    from fleet.sim.jsbsim_model import JSBSimModel

    wind = Wind(east=8.0)
    start = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=AIRSPEED)
    model = JSBSimModel(start, AircraftLimits(), MercatorProjection(*REFERENCE), wind)
    command = Command(bank=0.0, airspeed=AIRSPEED, altitude=600.0)
    for _ in range(3000):
        model.step(command, wind, STEP_MS / 1000.0)
    state = model.state
    assert state.x == pytest.approx(8.0 * 60.0, rel=0.03)
    assert state.y == pytest.approx(AIRSPEED * 60.0, rel=0.03)
    assert state.airspeed == pytest.approx(AIRSPEED, abs=0.3)
    sensors = model.sensors(wind)
    assert sensors.vel_east == pytest.approx(8.0, abs=0.3)
    assert sensors.vel_north == pytest.approx(AIRSPEED, abs=0.3)
    # JSBSim's wind is the one it flies in: set after the trim, which resets it.
    assert float(model.fdm["atmosphere/wind-east-fps"]) * 0.3048 == pytest.approx(8.0)


def test_the_telemetry_is_jsbsims_state() -> None:
    _jsbsim()
    wind = Wind(east=6.0)
    autopilot = SimulatedAutopilot(
        _uav(), AutopilotSettings(wind=wind, dynamics=Dynamics.JSBSIM, telemetry_hz=50.0)
    )
    while abs(autopilot.state.bank) < math.radians(20.0):  # into a turn
        autopilot.step()
        assert autopilot.time_ms < 300_000, "no turn in 5 simulated minutes"
    from fleet.sim.jsbsim_model import JSBSimModel

    assert isinstance(autopilot.model, JSBSimModel)
    fdm = autopilot.model.fdm
    telemetry = autopilot.telemetry()
    gps, sensor = telemetry.gps, telemetry.sensor
    assert gps is not None and sensor is not None
    assert gps.lat == pytest.approx(float(fdm["position/lat-geod-deg"]), abs=1e-7)
    assert gps.lon == pytest.approx(float(fdm["position/long-gc-deg"]), abs=1e-7)
    assert gps.alt == pytest.approx(float(fdm["position/h-sl-meters"]), abs=0.01)
    assert gps.vel_east == pytest.approx(float(fdm["velocities/v-east-fps"]) * 0.3048)
    assert sensor.roll == pytest.approx(float(fdm["attitude/phi-deg"]), abs=0.01)
    assert sensor.pitch == pytest.approx(float(fdm["attitude/theta-deg"]), abs=0.01)
    yaw = float(fdm["attitude/psi-deg"])
    assert math.cos(math.radians(sensor.yaw - yaw)) == pytest.approx(1.0)
    assert abs(sensor.roll) > 20.0


def test_a_jsbsim_flight_is_reproducible() -> None:
    _jsbsim()
    flights = []
    for _ in range(2):
        autopilot = SimulatedAutopilot(
            _uav(), AutopilotSettings(wind=Wind(east=5.0), dynamics=Dynamics.JSBSIM)
        )
        autopilot.advance_to(30_000)
        flights.append(autopilot.state)
    assert flights[0] == flights[1]


def test_an_airspeed_the_j3cub_cannot_fly_is_refused_naming_the_uav() -> None:
    _jsbsim()
    with pytest.raises(ValueError, match=r"uav 7: .*J3Cub flies at 20-35 m/s"):
        SimulatedAutopilot(_uav(airspeed=15.0), AutopilotSettings(dynamics=Dynamics.JSBSIM))


def test_without_jsbsim_the_error_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(sys.modules, "jsbsim", None)  # `import jsbsim` raises ImportError
    with pytest.raises(FlightModelError, match=r"pip install 'uav-fleet\[jsbsim\]'"):
        require(Dynamics.JSBSIM)
    require(Dynamics.KINEMATIC)  # the default needs nothing


def test_the_kinematic_model_is_still_the_default_and_unchanged() -> None:
    autopilot = SimulatedAutopilot(_uav())
    assert autopilot.settings.dynamics is Dynamics.KINEMATIC
    start = AircraftState(x=0.0, y=0.0, alt=600.0, heading=0.0, airspeed=AIRSPEED)
    expected = fly_to_point(start, PLAN_XY[0])
    flown, _, _ = _fly_to_first_waypoint(Wind(), Dynamics.KINEMATIC)
    assert flown == pytest.approx(expected, abs=STEP_MS / 1000.0)


def test_fleet_up_takes_dynamics_and_says_how_to_install_jsbsim_when_missing(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    parser = argparse.ArgumentParser()
    add_up_parser(parser.add_subparsers())
    options = up_options(parser.parse_args(["up", "--uavs", "2", "--dynamics", "jsbsim"]))
    assert options.dynamics is Dynamics.JSBSIM
    assert up_options(parser.parse_args(["up", "--uavs", "2"])).dynamics is Dynamics.KINEMATIC
    monkeypatch.setitem(sys.modules, "jsbsim", None)
    # Refused before anything starts: no router, simulator or onboard.
    assert fleet_cli.main(["up", "--uavs", "2", "--dynamics", "jsbsim"]) == ExitCode.USAGE
    assert "pip install 'uav-fleet[jsbsim]'" in capsys.readouterr().err
