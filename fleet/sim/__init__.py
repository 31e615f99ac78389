"""Simulated Piccolo autopilots: the hardware-in-the-loop stand-in (docs/simulator.md).

`aircraft` (point dynamics) and `guidance` (course pursuit, `fly_to_point`) are pure;
`flight_plan` is the waypoint table; `autopilot` is one simulated Piccolo, bytes in and
bytes out, stepped by simulated time; `scenario` loads scenario files; `server` is the
I/O edge (sockets, ptys, the clock).
"""

from fleet.sim.aircraft import AircraftState, Command, Wind
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.guidance import UnreachedError, fly_to_point, fly_until_arrival
from fleet.sim.scenario import (
    Scenario,
    ScenarioError,
    load_scenario,
    resolve_scenario,
    shipped_scenario,
    shipped_scenario_names,
    shipped_scenario_path,
)
from fleet.sim.uav_spec import UavSpec

__all__ = [
    "AircraftState",
    "AutopilotSettings",
    "Command",
    "Scenario",
    "ScenarioError",
    "SimulatedAutopilot",
    "UavSpec",
    "UnreachedError",
    "Wind",
    "fly_to_point",
    "fly_until_arrival",
    "load_scenario",
    "resolve_scenario",
    "shipped_scenario",
    "shipped_scenario_names",
    "shipped_scenario_path",
]
