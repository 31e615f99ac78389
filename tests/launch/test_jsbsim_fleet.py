"""A fleet flown on JSBSim, end to end: `fleet up --uavs 2 --dynamics jsbsim` (router,
simulator with each aircraft on its own JSBSim J3Cub, two onboard modules), two targets
sent with `ground-cli send-targets`, `mission --until-reached`, then the run's recording
read back. Each target is reached truthfully: the simulator's own telemetry (JSBSim's
position, as the UAVs put it on the bus) came within the onboard's acceptance radius of
it (REACHED_RADIUS_M, within which the onboard reports a target reached). The onboard's
predicted arrival (its approach-time model, the project's own physics) is compared with
the time flown on JSBSim (`fleet report`): the figure is logged; an ETA off by more than
the wind test's 10 % fails.
"""

from __future__ import annotations

import json
import logging
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from fleet.geo.mercator import MercatorProjection
from fleet.launch.endpoints import free_port
from fleet.launch.ring import GENERATED_CENTRE
from fleet.mission.target_checks import REACHED_RADIUS_M
from tests.support.ground_view import GroundView
from tests.support.processes import client_session, start_fleet_up, wait_fleet_up

pytest.importorskip("jsbsim", reason="JSBSim is not installed: pip install '.[jsbsim]'")
pytestmark = pytest.mark.e2e

log = logging.getLogger(__name__)

TIMEOUT_S = 120.0
#: How far a published ETA may be from the time flown (as tests/launch/test_wind_prediction).
TOLERANCE = 0.10
#: `fleet up --uavs 2` puts UAV 101 at (0, 1500) flying west and 102 at (0, -1500)
#: flying east (fleet.launch.ring); each target is 1.7 km ahead and to the right of one.
TARGETS_XY = ((-1400.0, 2400.0), (1400.0, -2400.0))


def run(*argv: str, timeout: float = TIMEOUT_S) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, timeout=timeout, check=False
    )


def test_two_uavs_on_jsbsim_reach_their_targets(tmp_path: Path) -> None:
    projection = MercatorProjection(*GENERATED_CENTRE)
    targets = tmp_path / "targets.csv"
    rows = ["lat,lon,alt"]
    for x, y in TARGETS_XY:
        lat, lon = projection.to_latlon(x, y)
        rows.append(f"{lat:.7f},{lon:.7f},600")
    targets.write_text("\n".join(rows) + "\n")

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    up = start_fleet_up(
        "--uavs", "2", "--dynamics", "jsbsim", "--listen", endpoint, "--speedup", "4",
        "--log-dir", str(tmp_path),
    )  # fmt: skip
    try:
        wait_fleet_up(up, 90.0)
        # Every telemetry sample the UAVs put on the bus, the fix that proved each arrival
        # among them (the recording keeps one sample per 0.2 s, and ends at the stop).
        with client_session(endpoint) as session:
            seen = GroundView(session)
            try:
                ground = ("-m", "ground.cli", "--connect", endpoint)
                sent = run(*ground, "send-targets", str(targets), "--wait", "--json",
                           "--timeout", "60")  # fmt: skip
                assert sent.returncode == 0, sent.stderr[-3000:]
                outcome = json.loads(sent.stdout)
                assert outcome["agreed"] is True
                assert outcome["assignment"] == {"101": 0, "102": 1}
                # ~80 s simulated each: ~20 s at speedup 4.
                reached = run(*ground, "mission", "--until-reached", "200", "--json", timeout=240.0)
                assert reached.returncode == 0, reached.stdout[-3000:] + reached.stderr[-3000:]
                closest = {
                    uav: seen.closest_approach(uav, *projection.to_latlon(*target))
                    for uav, target in ((101, TARGETS_XY[0]), (102, TARGETS_XY[1]))
                }
            finally:
                seen.close()
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(60) == 0
    # The simulator flew JSBSim, not the kinematic model.
    assert "(jsbsim dynamics)" in (tmp_path / "sim.log").read_text()

    # Reached truthfully: the simulator's telemetry (JSBSim's position) came within the
    # onboard's acceptance radius of each target.
    for number, distance in closest.items():
        log.info("UAV %s: closest approach to its target %.1f m", number, distance)
        assert distance <= REACHED_RADIUS_M, (number, distance)

    # The onboard's prediction (the project's own model) against the JSBSim flight.
    report = run("-m", "programs.fleet_cli", "report", str(tmp_path / "fleet.mcap"), "--json")
    assert report.returncode == 0, report.stderr[-3000:]
    (mission,) = json.loads(report.stdout)["missions"]
    for uav in ("101", "102"):
        predicted, flown = mission["predicted_s"][uav], mission["flown_s"][uav]
        assert predicted is not None and flown is not None, (uav, mission)
        log.info(
            "UAV %s on JSBSim: predicted %.1f s, flown %.1f s (%+.1f %%)",
            uav,
            predicted,
            flown,
            100.0 * (predicted - flown) / flown,
        )
        assert abs(predicted - flown) <= TOLERANCE * flown, (uav, predicted, flown)
