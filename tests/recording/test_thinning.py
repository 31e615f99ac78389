"""Telemetry thinned in a recording: one per key per interval; everything else kept."""

from __future__ import annotations

from fleet.recording.thinning import TelemetryThinning

TELEMETRY = "fleet/uav/*/telemetry"
MS = 1_000_000


def test_one_telemetry_per_key_per_interval_and_the_rest_counted() -> None:
    thinning = TelemetryThinning(0.2)
    kept = [
        t for t in range(0, 1000, 50) if thinning.keep("fleet/uav/7/telemetry", TELEMETRY, t * MS)
    ]
    assert kept == [0, 200, 400, 600, 800]
    assert thinning.thinned == 15
    # Another UAV's telemetry has its own interval.
    assert thinning.keep("fleet/uav/8/telemetry", TELEMETRY, 50 * MS)


def test_anything_but_telemetry_is_kept_and_zero_keeps_everything() -> None:
    thinning = TelemetryThinning(0.2)
    assert all(thinning.keep("fleet/uav/7/status", "fleet/uav/*/status", t) for t in range(5))
    every = TelemetryThinning(0.0)
    assert all(every.keep("fleet/uav/7/telemetry", TELEMETRY, t) for t in range(5))
    assert thinning.thinned == every.thinned == 0


def test_a_clock_that_goes_back_starts_the_interval_again() -> None:
    thinning = TelemetryThinning(0.2)
    assert thinning.keep("k/telemetry", TELEMETRY, 1000 * MS)
    assert thinning.keep("k/telemetry", TELEMETRY, 500 * MS)
    assert not thinning.keep("k/telemetry", TELEMETRY, 600 * MS)
