"""Each aircraft's streams (fleet.recording.streams): counted per UAV and channel, a
stopped telemetry stream found while the fleet runs and in a finished recording."""

from __future__ import annotations

from fleet.recording.streams import StreamCounts, short_streams, stopped_telemetry


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def fly(counts: StreamCounts, clock: Clock, seconds: float, uavs: list[int]) -> None:
    """Telemetry of `uavs` five times a second for `seconds`."""
    for _ in range(round(seconds * 5)):
        clock.now += 0.2
        for uav in uavs:
            counts.heard(f"fleet/uav/{uav}/telemetry", {})


def test_samples_are_counted_per_uav_and_channel() -> None:
    counts = StreamCounts("fleet", Clock())
    for key in ["fleet/uav/7/telemetry", "fleet/uav/7/telemetry", "fleet/uav/7/state"]:
        counts.heard(key, {})
    counts.heard("fleet/uav/8/state", {})
    counts.heard("fleet/mission/1/targets", {})  # not a UAV's
    counts.heard("other/uav/9/telemetry", {})  # another prefix
    assert counts.counts == {(7, "telemetry"): 2, (7, "state"): 1, (8, "state"): 1}
    assert counts.telemetry() == {7: 2, 8: 0}


def test_telemetry_is_compared_over_the_window_every_uav_flies() -> None:
    clock = Clock()
    counts = StreamCounts("fleet", clock)
    fly(counts, clock, 1.0, [1, 2])  # UAV 3's onboard started a second later
    counts.open_window()
    fly(counts, clock, 4.0, [1, 2, 3])
    counts.close_window()
    fly(counts, clock, 1.0, [3])  # and ended a second later
    assert counts.telemetry() == {1: 20, 2: 20, 3: 20}
    assert counts.counts[3, "telemetry"] == 25  # the totals stay as recorded


def test_a_stream_that_stopped_in_the_window_is_short() -> None:
    clock = Clock()
    counts = StreamCounts("fleet", clock)
    fly(counts, clock, 0.2, [1, 2, 3])
    counts.open_window()
    fly(counts, clock, 0.2, [1, 2, 3])
    fly(counts, clock, 10.0, [2, 3])  # UAV 1's stopped
    counts.close_window()
    assert counts.telemetry() == {1: 1, 2: 51, 3: 51}
    assert short_streams(counts.telemetry()) == [
        "UAV 1's telemetry: 1 samples recorded, the median UAV's 51"
    ]


def test_a_uav_whose_telemetry_stops_while_the_others_flow_is_stalled() -> None:
    clock = Clock()
    counts = StreamCounts("fleet", clock)
    fly(counts, clock, 2.0, [1, 2, 3])
    assert counts.stalled() == []
    fly(counts, clock, 10.0, [1, 3])
    (stall,) = counts.stalled()
    assert (stall.uav, stall.samples) == (2, 10)
    assert 9.0 < stall.silent_s < 11.0
    assert "UAV 2's telemetry stopped" in str(stall)
    fly(counts, clock, 1.0, [1, 2, 3])  # it came back
    assert counts.stalled() == []


def test_a_uav_that_never_had_telemetry_but_whose_state_comes_is_stalled() -> None:
    clock = Clock()
    counts = StreamCounts("fleet", clock)
    for _ in range(10):
        clock.now += 1.0
        counts.heard("fleet/uav/5/state", {})
    assert [stall.uav for stall in counts.stalled()] == [5]


def test_a_fleet_that_went_quiet_or_a_uav_that_left_is_not_stalled() -> None:
    clock = Clock()
    counts = StreamCounts("fleet", clock)
    fly(counts, clock, 2.0, [1, 2])
    clock.now += 30.0  # nothing flows: the fleet stopped, not one stream
    assert counts.stalled() == []
    counts.heard("fleet/uav/2/alive", {"alive": False})
    fly(counts, clock, 10.0, [1])
    assert counts.stalled() == []  # its onboard left: told as a lost child, not here


def test_short_streams_names_the_uavs_far_below_the_median() -> None:
    assert short_streams({101: 3, 102: 7200, 103: 7150, 104: 7210}) == [
        "UAV 101's telemetry: 3 samples recorded, the median UAV's 7200"
    ]
    assert short_streams({101: 6900, 102: 7200}) == []
    assert short_streams({101: 3}) == []


def test_stopped_telemetry_of_a_finished_recording() -> None:
    lines = stopped_telemetry({101: 0.008, 102: 45.0, 103: None, 104: 44.9}, {101: 3, 102: 7200})
    assert lines == [
        "UAV 101's telemetry stopped at 0.0 s (3 samples) while others' went on to 45.0 s",
        "UAV 103 has no telemetry in the recording; others do",
    ]
    assert stopped_telemetry({101: 40.0, 102: 43.0}, {}) == []
    assert stopped_telemetry({101: None}, {}) == []
