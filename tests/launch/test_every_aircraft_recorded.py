"""Every aircraft recorded: `fleet up` with 4 UAVs records each one's telemetry, none
cut short (an onboard's telemetry publisher once lost the recorder at start-up: see
fleet.launch.launcher's watch, and bench/zenoh_write_filter.py)."""

from __future__ import annotations

import signal
import statistics
from collections import Counter
from pathlib import Path

import pytest

from fleet.recording.reader import RecordingError, read_recording
from tests.support.processes import ANY_PORT, start_fleet_up, wait_fleet_up
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

UAVS = (101, 102, 103, 104)
#: Telemetry samples the median UAV has in the file before the fleet is stopped: 30 s of
#: flight at 5 recorded a second, long after every onboard's start.
SAMPLES = 150
#: A UAV's telemetry is whole within this ratio of the median (a loaded machine delays
#: one onboard's start by seconds, never by most of the run).
RATIO = 0.5


def telemetry_counts(path: Path) -> Counter[int]:
    try:
        recording = read_recording(path)
    except RecordingError:
        return Counter()  # not written yet
    counts: Counter[int] = Counter()
    for topic, count in recording.counts().items():
        parts = topic.split("/")
        if len(parts) == 4 and parts[1] == "uav" and parts[3] == "telemetry":
            counts[int(parts[2])] += count
    return counts


def test_a_recording_of_four_uavs_has_every_uavs_telemetry(tmp_path: Path) -> None:
    up = start_fleet_up(
        "--uavs",
        str(len(UAVS)),
        "--speedup",
        "10",
        "--listen",
        ANY_PORT,
        "--log-dir",
        str(tmp_path),
    )
    recording = tmp_path / "fleet.mcap"
    try:
        wait_fleet_up(up, 120.0)
        wait_until(
            lambda: statistics.median(telemetry_counts(recording)[u] for u in UAVS) >= SAMPLES,
            300.0,
            f"{SAMPLES} telemetry samples of the median UAV in the recording",
        )
    finally:
        up.process.send_signal(signal.SIGTERM)
        status = up.process.wait(60)
    output = "\n".join(up.history)
    assert status == 0, output
    counts = telemetry_counts(recording)
    median = statistics.median(counts[uav] for uav in UAVS)
    assert all(counts[uav] >= RATIO * median for uav in UAVS), (counts, output)
    assert "telemetry stopped" not in output and "samples recorded" not in output, output
