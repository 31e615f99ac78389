"""Record a 2-UAV mission through `fleet up`, kill a second recorder, replay, plot, report.

Real processes throughout: `fleet up` (router, simulator, two onboards, its recorder),
a second `fleet record` killed with SIGKILL mid-mission, `ground-cli`, `fleet replay`
on a router of its own, `fleet plot` and `fleet report`.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import threading
from collections import Counter
from importlib.resources import files
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from fleet.mission.key_space import KeySpace
from fleet.recording import channels
from fleet.recording.reader import read_recording
from fleet.recording.recorder import DEFAULT_FIX_EVERY_S
from fleet.recording.thinning import DEFAULT_TELEMETRY_EVERY_S
from fleet.transport.cli import PREFIX_ENV
from tests.support.ground_cli import ground_cli
from tests.support.processes import (
    ANY_PORT,
    Child,
    client_session,
    start,
    start_fleet_up,
    start_router,
    wait_fleet_up,
)
from tests.support.waiting import wait_until

SPACE = KeySpace()

pytestmark = pytest.mark.e2e

TIMEOUT_S = 120
FLEET = ("-m", "programs.fleet_cli")
TEAM = {74, 112}
#: A generous bound on a recording's size (compressed, telemetry at 5 Hz).
MAX_BYTES_PER_AIRCRAFT_MINUTE = 265_000


def run(*argv: str, prefix: str | None = None) -> subprocess.CompletedProcess[str]:
    env = None if prefix is None else {**os.environ, PREFIX_ENV: prefix}
    return subprocess.run(
        [sys.executable, *argv],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        check=False,
        env=env,
    )


def uavs(endpoint: str, prefix: str) -> list[dict[str, object]]:
    """`ground-cli uavs --json` under `prefix`: the flag for a replay, else the environment."""
    if prefix == "replay":
        done = ground_cli(
            "--key-prefix", prefix, "uavs", "--json", connect=endpoint, timeout=TIMEOUT_S
        )
    else:
        done = ground_cli(
            "uavs", "--json", connect=endpoint, env={PREFIX_ENV: prefix}, timeout=TIMEOUT_S
        )
    assert done.returncode == 0, done.stderr
    listed: list[dict[str, object]] = json.loads(done.stdout)
    return listed


def check_telemetry_counts(path: Path) -> None:
    """One telemetry per `DEFAULT_TELEMETRY_EVERY_S` of the recording's clock per UAV (the
    fleet sends 20 Hz of its own clock, 200 Hz of the wall's at speedup 10); one map fix
    per UAV per `DEFAULT_FIX_EVERY_S`, the first on its first telemetry.
    """
    recording = read_recording(path)
    # A telemetry comes every 5 ms of wall clock at speedup 10: late by a busy machine.
    late_s = 1.0
    for uav in TEAM:
        telemetry = [m for m in recording.messages if m.topic == f"fleet/uav/{uav}/telemetry"]
        gaps = [(b.log_time_ns - a.log_time_ns) / 1e9 for a, b in itertools.pairwise(telemetry)]
        every = DEFAULT_TELEMETRY_EVERY_S
        assert len(gaps) > 10 and all(every <= gap < every + late_s for gap in gaps), gaps
        fixes = [m for m in recording.messages if m.topic == f"fleet/uav/{uav}/location_fix"]
        assert fixes[0].log_time_ns == telemetry[0].log_time_ns
        gaps = [(b.log_time_ns - a.log_time_ns) / 1e9 for a, b in itertools.pairwise(fixes)]
        assert all(DEFAULT_FIX_EVERY_S <= gap < DEFAULT_FIX_EVERY_S + late_s for gap in gaps), gaps
        span_s = (telemetry[-1].log_time_ns - fixes[-1].log_time_ns) / 1e9
        assert span_s < DEFAULT_FIX_EVERY_S + late_s, span_s


def check_size(path: Path) -> None:
    """Compressed, with telemetry thinned: a recording is small per aircraft-minute."""
    recording = read_recording(path)
    minutes = (recording.messages[-1].log_time_ns - recording.messages[0].log_time_ns) / 60e9
    per_aircraft_minute = path.stat().st_size / (len(TEAM) * minutes)
    # About 170 KB measured at speedup 1, 1.3 MB before compression and thinning
    # (docs/benchmarks.md): the bound is a fifth of before.
    assert per_aircraft_minute < MAX_BYTES_PER_AIRCRAFT_MINUTE, per_aircraft_minute


def check_schemas(path: Path) -> None:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    names = {schema.name for schema in summary.schemas.values()}
    assert {"Telemetry", "UavState", "MissionTargets", "AssignmentReport", "UavResult"} <= names
    assert channels.LOCATION_FIX in names
    assert all(s.encoding == "jsonschema" and s.data for s in summary.schemas.values())
    for channel in summary.channels.values():
        assert channel.message_encoding == "json"
        assert channel.schema_id != 0, f"{channel.topic} has no schema"
    fixes = [c for c in summary.channels.values() if c.topic.endswith("/location_fix")]
    assert {c.topic for c in fixes} == {f"fleet/uav/{u}/location_fix" for u in TEAM}


def wait_reached(endpoint: str) -> None:
    def every_uav_reached() -> bool:
        phases = {view["id"]: view["phase"] for view in uavs(endpoint, "fleet")}
        return set(phases) == TEAM and all(p == "reached" for p in phases.values())

    wait_until(every_uav_reached, 150.0, "both UAVs to reach their targets")


def test_record_a_mission_kill_a_recorder_replay_and_plot(tmp_path: Path) -> None:
    up = start_fleet_up(
        "head_on", "--listen", ANY_PORT, "--speedup", "10", "--log-dir", str(tmp_path / "run")
    )
    second: Child | None = None
    try:
        endpoint = wait_fleet_up(up, 90.0).connect
        assert any("recording to" in line for line in up.history)
        second = start(
            "fleet record",
            [sys.executable, *FLEET, "record", str(tmp_path / "second.mcap"),
             "--connect", endpoint],
        )  # fmt: skip
        second.wait_for_line(lambda line: line.startswith("fleet record: recording"), 30.0)
        targets = str(files("fleet") / "scenarios" / "head_on_targets.bin")
        sent = ground_cli("send-targets", targets, "--wait", connect=endpoint, timeout=TIMEOUT_S)
        assert sent.returncode == 0, sent.stdout + sent.stderr
        wait_reached(endpoint)
        second.process.send_signal(signal.SIGKILL)
        second.process.wait(10)
    finally:
        if second is not None:
            second.kill()
        assert up.stop() == 0, "\n".join(up.history[-20:])

    # The killed recorder's file reads back, up to where it was killed.
    killed = read_recording(tmp_path / "second.mcap")
    assert str(tmp_path / "second.mcap") in killed.truncated
    assert killed.counts()["fleet/mission/1/assignment/74"] == 1
    check_telemetry_counts(tmp_path / "second.mcap")

    recorded = tmp_path / "run" / "fleet.mcap"
    check_schemas(recorded)
    check_telemetry_counts(recorded)
    check_size(recorded)
    _replay_and_see_it(recorded, tmp_path)

    plotted = run(*FLEET, "plot", str(recorded), "--out", str(tmp_path / "mission.png"))
    assert plotted.returncode == 0, plotted.stderr
    assert (tmp_path / "mission.png").read_bytes()[:4] == b"\x89PNG"
    reported = run(*FLEET, "report", str(recorded), "--json")
    assert reported.returncode == 0, reported.stderr
    (mission,) = json.loads(reported.stdout)["missions"]
    assert mission["agreed"] is True
    assert mission["assignment"] == {"74": 0, "112": 1}
    assert mission["reached"] == {"74": True, "112": True}
    assert all(mission["flown_s"][u] > 0 for u in ("74", "112"))


def _replay_and_see_it(recorded: Path, tmp_path: Path) -> None:
    """Replay at 10x on a router of its own; the ground sees the UAVs under `replay`."""
    router, endpoint = start_router("--listen", ANY_PORT)
    replay: Child | None = None
    heard: Counter[str] = Counter()
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            heard[str(sample.key_expr)] += 1

    try:
        with client_session(endpoint) as session, session.declare_subscriber("**", on_sample):
            replay = start(
                "fleet replay",
                [sys.executable, *FLEET, "replay", str(recorded), "--rate", "10",
                 "--connect", endpoint, "--hold", "60"],
            )  # fmt: skip
            seen: list[dict[str, object]] = []

            def replayed_positions() -> bool:
                seen[:] = uavs(endpoint, "replay")
                return {v["id"] for v in seen} == TEAM and all(v["lat"] is not None for v in seen)

            wait_until(replayed_positions, 60.0, "ground-cli uavs to list the replayed UAVs")
            tracks = read_recording(recorded)
            for view in seen:
                lats = [
                    m.value()["gps"]["lat"]
                    for m in tracks.messages
                    if m.topic == f"fleet/uav/{view['id']}/telemetry"
                ]
                assert min(lats) <= float(str(view["lat"])) <= max(lats)
            # Under the live prefix there is nothing: a replay is never the live fleet.
            assert uavs(endpoint, "fleet") == []
            replay.wait_for_line(lambda line: "end reached" in line, 60.0)
        with lock:
            keys_heard = set(heard)
        assert keys_heard and all(key.startswith("replay/") for key in keys_heard)
        assert not [key for key in keys_heard if channels.is_command(key)]
        assert "replay/uav/74/telemetry" in keys_heard
    finally:
        if replay is not None:
            replay.stop()
        router.stop()
