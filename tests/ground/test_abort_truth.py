"""An aborted mission is reported aborted, end to end: real simulator, onboard
processes, router and `ground-cli`. The operator aborts one UAV alone while the team
flies, then the whole mission; each time `ground-cli mission` must name the aborted
targets and their UAVs and exit non-zero, never `success` with its targets `assigned`;
and `fleet report` on the recording of it must count no UAV as having flown to its
target (the abort turned it back to its course: no arrival).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from onboard.core import TARGET_WAYPOINT
from tests.conftest import Ground
from tests.ground.test_truth import listed_uavs, targets_file
from tests.onboard.test_multi_uav import start_ring
from tests.support.ground_cli import finish_ground_cli, start_ground_cli
from tests.support.processes import Fleet, start
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

#: Real time: the targets (0.5-2.5 km away) stay unreached for the whole test.
SPEEDUP = 1.0


def mission_report(ground: Ground) -> tuple[int, dict[str, Any], str]:
    status, out, err = finish_ground_cli(
        start_ground_cli("mission", "--json", connect=ground.router), 30
    )
    return status, json.loads(out), err


def phases(ground: Ground) -> dict[int, str]:
    return {row["id"]: row["phase"] for row in listed_uavs(ground)}


def test_an_aborted_uav_s_target_and_an_aborted_mission_are_reported_aborted(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    team = start_ring(fleet, ground, tmp_path, 2, speedup=SPEEDUP)
    seen = ground.seen
    recording = tmp_path / "abort.mcap"
    recorder = start(
        "fleet record",
        [sys.executable, "-m", "programs.fleet_cli", "record", str(recording),
         "--connect", ground.router],
    )  # fmt: skip
    fleet.children.append(recorder)
    recorder.wait_for_line(lambda line: line.startswith("fleet record: recording"), 30.0)
    path = targets_file(tmp_path, ring_targets(2, seed=5))
    assert (
        finish_ground_cli(start_ground_cli("send-targets", str(path), connect=ground.router), 60)[0]
        == 0
    )
    wait_until(
        lambda: all(any("flying to target" in s for s in seen.statuses(u)) for u in team),
        60.0,
        "both UAVs flying to their targets",
    )
    status, report, err = mission_report(ground)
    assert status == 0 and report["success"] is True, err
    target_of = {int(uav): target for uav, target in report["assignment"].items()}
    alone, other = team

    # The fault, first: one UAV aborted alone; its teammate flies on.
    assert (
        finish_ground_cli(
            start_ground_cli("abort", "--uav", str(alone), connect=ground.router), 30
        )[0]
        == 0
    )
    wait_until(lambda: phases(ground).get(alone) == "aborted", 30.0, f"UAV {alone} aborted")
    status, report, err = mission_report(ground)
    states = {s["index"]: s for s in report["target_states"]}
    assert states[target_of[alone]]["state"] == "aborted", report["target_states"]
    assert states[target_of[alone]]["uav"] == alone
    assert (states[target_of[other]]["state"], states[target_of[other]]["uav"]) == (
        "assigned",
        other,
    )
    assert report["success"] is False
    assert status == 1, err

    # Then the whole mission.
    assert finish_ground_cli(start_ground_cli("abort", connect=ground.router), 30)[0] == 0
    wait_until(lambda: set(phases(ground).values()) == {"aborted"}, 30.0, "every UAV aborted")
    status, report, err = mission_report(ground)
    assert [(s["state"], s["uav"]) for s in report["target_states"]] == [
        ("aborted", uav) for uav in sorted(team, key=lambda u: target_of[u])
    ]
    assert report["success"] is False
    assert status == 1, err
    # What the aircraft did: neither reached its target; both turned back to course.
    wait_until(
        lambda: all(seen.latest_track(u) not in (None, TARGET_WAYPOINT) for u in team),
        30.0,
        "both UAVs back on their course",
    )
    assert not any(s.startswith("reached") for u in team for s in seen.statuses(u))

    # The recording of it says the same (before: 'flown ... s (track)' for each).
    assert recorder.stop() == 0, "\n".join(recorder.history[-10:])
    status, out, err = finish_ground_cli(fleet_cli("report", str(recording), "--json"), 60)
    assert status == 0, err
    (mission,) = json.loads(out)["missions"]
    assert mission["reached"] == {str(u): False for u in team}, mission
    assert mission["flown_s"] == {str(u): None for u in team}
    assert {how["how"] for how in mission["ended"].values()} == {"aborted"}
    status, out, err = finish_ground_cli(fleet_cli("report", str(recording)), 60)
    assert status == 0 and "flown" not in out and "ABORTED at" in out, out + err
    status, _, err = finish_ground_cli(
        fleet_cli("plot", str(recording), "--out", str(tmp_path / "a.png")), 60
    )
    assert status == 0, err


def fleet_cli(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "programs.fleet_cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
