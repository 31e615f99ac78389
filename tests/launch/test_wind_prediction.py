"""Predicted arrivals hold in wind, end to end: `fleet up` (router, simulator, three
onboard modules) on a scenario with a 10 m/s wind that drifts and gusts, and whose
reported estimate lags and errs; `ground-cli send-targets` and `mission
--until-reached`; then `fleet report` on the run's own recording compares each UAV's
published ETA with the time it flew (on the aircraft's clock, from its commitment to
its arrival: docs/recording.md).

Each UAV has its own target 3 km away: one upwind, one downwind, one across the wind.
In still air the Dubins time to the upwind and downwind targets is 30-40 % off the
flown time, so the test fails if the wind is not in the plan.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from fleet.files.targets_io import write_targets
from fleet.geo.aircraft import turn_radius
from fleet.geo.dubins import dubins_time_in_wind, dubins_time_to_point
from fleet.geo.mercator import MercatorProjection
from fleet.geo.wind import Wind
from fleet.launch.launcher import free_port
from fleet.mission.messages import Target
from tests.support.processes import start

pytestmark = pytest.mark.e2e

TIMEOUT_S = 120.0
CENTRE = (35.72, -120.76)
AIRSPEED = 22.0
WIND_EAST = 10.0  # blows to the east: from the west
#: Each UAV: Piccolo ID, start (east, north) in metres, heading (degrees), and its
#: target's offset from its start. 8 km apart, so each target is its own UAV's best.
UAVS = (
    (201, (0.0, 0.0), 0.0, (-3000.0, 1000.0)),  # heading north; target upwind
    (202, (0.0, -8000.0), 0.0, (3000.0, 1000.0)),  # heading north; target downwind
    (203, (0.0, 8000.0), 90.0, (1000.0, 3000.0)),  # heading east; target across the wind
)
#: How far a published ETA may be from the time flown.
TOLERANCE = 0.10


def scenario_text() -> str:
    projection = MercatorProjection(*CENTRE)
    lines = [
        'description = "three UAVs in a 10 m/s westerly that drifts and gusts"',
        "",
        "[wind]",
        f"east = {WIND_EAST}",
        "drift_speed = 0.5",
        "drift_direction = 5.0",
        "gust = 0.8",
        "estimate_lag = 10.0",
        "estimate_error = 0.4",
        "seed = 24",
        "",
    ]
    for uav, (east, north), heading, _ in UAVS:
        lat, lon = projection.to_latlon(east, north)
        lines += [
            "[[uav]]",
            f"id = {uav}",
            f"lat = {lat:.7f}",
            f"lon = {lon:.7f}",
            "alt = 600.0",
            f"heading = {heading}",
            f"airspeed = {AIRSPEED}",
            "",
        ]
    return "\n".join(lines)


def targets() -> tuple[Target, ...]:
    projection = MercatorProjection(*CENTRE)
    found = []
    for _, (east, north), _, (dx, dy) in UAVS:
        lat, lon = projection.to_latlon(east + dx, north + dy)
        found.append(Target(lat, lon, 600.0))
    return tuple(found)


def run(*argv: str, timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, timeout=timeout, check=False
    )


def test_still_air_times_would_fail_this_test() -> None:
    """The scenario is one where the wind matters: without it, the ETAs are far off."""
    radius = turn_radius(AIRSPEED, 30.0)
    for _, _, heading, offset in UAVS[:2]:
        h = math.radians(heading)
        air = (AIRSPEED * math.sin(h), AIRSPEED * math.cos(h))
        still = dubins_time_to_point((0.0, 0.0), air, offset, radius)
        windy = dubins_time_in_wind((0.0, 0.0), air, offset, radius, Wind(WIND_EAST, 0.0))
        assert abs(still - windy) > 2 * TOLERANCE * windy


def test_three_uavs_arrive_when_they_said_in_a_10_ms_wind(tmp_path: Path) -> None:
    scenario = tmp_path / "windy.toml"
    scenario.write_text(scenario_text())
    targets_path = tmp_path / "targets.bin"
    write_targets(targets_path, targets())
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    logs = tmp_path / "logs"
    up = start(
        "fleet up",
        [sys.executable, "-m", "ground.fleet_cli", "up", str(scenario), "--listen", endpoint,
         "--speedup", "3", "--log-dir", str(logs)],
    )  # fmt: skip
    try:
        up.wait_for_line(lambda line: "stops the fleet" in line, 90.0)
        ground = ("-m", "ground.cli", "--connect", endpoint)
        sent = run(*ground, "send-targets", str(targets_path), "--wait", "--json",
                   "--timeout", "60")  # fmt: skip
        assert sent.returncode == 0, sent.stderr[-3000:]
        outcome = json.loads(sent.stdout)
        assert outcome["agreed"] is True
        assert outcome["assignment"] == {"201": 0, "202": 1, "203": 2}
        # The longest flight (upwind, ~240 s simulated) is ~80 s at speedup 3.
        reached = run(*ground, "mission", "--until-reached", "240", "--json", timeout=300.0)
        assert reached.returncode == 0, reached.stdout[-3000:] + reached.stderr[-3000:]
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(60) == 0
    report = run("-m", "ground.fleet_cli", "report", str(logs / "fleet.mcap"), "--json")
    assert report.returncode == 0, report.stderr[-3000:]
    (mission,) = json.loads(report.stdout)["missions"]
    for uav in ("201", "202", "203"):
        predicted, flown = mission["predicted_s"][uav], mission["flown_s"][uav]
        assert predicted is not None and flown is not None, (uav, mission)
        assert abs(predicted - flown) <= TOLERANCE * flown, (uav, predicted, flown)
