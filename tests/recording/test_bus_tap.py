"""The bus tap (fleet.recording.bus_tap) on the in-memory bus, with a sink that notes
what it is handed: the same tap the recorder and the Foxglove bridge write from."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import StatusText
from fleet.recording.bus_tap import BusTap, Heard, ended_line
from fleet.recording.channels import ChannelSpec
from fleet.transport import bus_codec
from fleet.transport.bus import BusSample
from fleet.transport.memory import MemoryNetwork
from tests.support.waiting import wait_until

SPACE = KeySpace()


class NotingSink:
    def __init__(self, keep_telemetry: bool = True) -> None:
        self.written: list[tuple[Heard, ChannelSpec, Any]] = []
        self.offered: list[str] = []
        self.ticks = 0
        self.keep_telemetry = keep_telemetry

    def keep(self, heard: Heard, spec: ChannelSpec) -> bool:
        self.offered.append(heard.key)
        return self.keep_telemetry or not heard.key.endswith("/telemetry")

    def write(self, heard: Heard, spec: ChannelSpec, value: Any) -> None:
        self.written.append((heard, spec, value))

    def tick(self) -> None:
        self.ticks += 1


def tap_on(sink: NotingSink, **options: Any) -> tuple[BusTap, Any]:
    network = MemoryNetwork()
    fleet, ground = network.bus(), network.bus()
    options.setdefault("state_every_s", 0)
    tap = BusTap(ground, sink, SPACE, queue_limit=100, batch_s=0.01, **options)
    return tap, fleet


@pytest.mark.parametrize("ring", [False, True], ids=["callback", "ring"])
def test_what_is_heard_goes_to_the_sink_on_its_channel(ring: bool) -> None:
    sink = NotingSink()
    tap, fleet = tap_on(sink, ring_limit=10 if ring else None)
    tap.start()
    try:
        fleet.publish(SPACE.status(7), StatusText("hello"))
        token = fleet.declare_token(SPACE.alive(7))
        wait_until(lambda: len(sink.written) == 2, 10.0, "the put and the token")
        token.undeclare()
        wait_until(lambda: len(sink.written) == 3, 10.0, "the token going")
    finally:
        tap.stop()
    # The ring is read after the callbacks' queue: order only within one key.
    ((_, spec, value),) = [w for w in sink.written if w[0].key == SPACE.status(7)]
    assert value["text"] == "hello" and spec.pattern == "fleet/uav/*/status"
    alive, gone = [w for w in sink.written if w[0].key == SPACE.alive(7)]
    assert (alive[0].payload, gone[0].payload) == (b'{"alive":true}', b'{"alive":false}')
    assert alive[1].schema_name == "fleet.Liveliness" and sink.ticks > 0
    assert tap.dropped == {}


def test_the_router_timestamp_is_the_time_and_a_delete_is_dropped() -> None:
    sink = NotingSink()
    tap, _ = tap_on(sink)
    tap.start()
    tap.on_sample(BusSample(SPACE.status(7), bus_codec.encode(StatusText("x")), time_ns=42))
    tap.on_sample(BusSample(SPACE.status(7), b"", deleted=True))
    tap.stop()  # hands the sink what is queued
    assert [heard.time_ns for heard, _, _ in sink.written] == [42]
    assert tap.dropped == {"delete": 1}


def test_the_sink_thins_before_anything_is_decoded_and_bad_input_is_counted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    sink = NotingSink(keep_telemetry=False)
    tap, _ = tap_on(sink, refused="not kept")
    tap.start()
    tap.on_sample(BusSample(SPACE.telemetry(7), b"\xff not even JSON"))  # thinned: never decoded
    tap.on_sample(BusSample(SPACE.status(7), b"\xff not JSON"))
    tap.on_sample(BusSample(SPACE.status(7), b"\xff nor this"))
    tap.on_sample(BusSample(SPACE.status(8), b"[" * 5000 + b"]" * 5000))
    tap.stop()
    assert sink.written == [] and SPACE.telemetry(7) in sink.offered
    assert tap.dropped == {"not JSON": 2, "too_deep": 1}
    assert len([r for r in caplog.records if "not kept" in r.message]) == 2  # once per key


def test_keys_beyond_the_limits_are_dropped_and_counted() -> None:
    sink = NotingSink()
    tap, _ = tap_on(sink, max_unknown_keys=2, name="writer")
    tap.start()
    for i in range(4):
        tap.on_sample(BusSample(f"fleet/uav/7/junk-{i}", b"1"))
    tap.on_sample(BusSample("fleet/uav/7/junk-0", b"2"))  # a key that has its channel
    tap.on_sample(BusSample(SPACE.status(7), bus_codec.encode(StatusText("known"))))
    tap.stop()
    assert [heard.key for heard, _, _ in sink.written] == [
        "fleet/uav/7/junk-0",
        "fleet/uav/7/junk-1",
        "fleet/uav/7/junk-0",
        SPACE.status(7),
    ]
    assert tap.dropped == {"too many unknown keys": 2}
    capped, _ = tap_on(NotingSink(), max_channels=1)
    capped.start()
    capped.on_sample(BusSample(SPACE.status(7), bus_codec.encode(StatusText("a"))))
    capped.on_sample(BusSample(SPACE.status(8), bus_codec.encode(StatusText("b"))))
    capped.stop()
    assert capped.dropped == {"too many keys": 1}


def test_a_full_queue_drops_and_counts_and_a_failing_sink_stops_the_tap() -> None:
    class FullDisk(NotingSink):
        def write(self, heard: Heard, spec: ChannelSpec, value: Any) -> None:
            raise OSError(28, "No space left on device")

    failures: list[OSError] = []
    tap, _ = tap_on(FullDisk(), on_failure=failures.append)
    tap._queue_limit = 1
    tap.on_sample(BusSample(SPACE.status(7), bus_codec.encode(StatusText("a"))))
    tap.on_sample(BusSample(SPACE.status(7), bus_codec.encode(StatusText("b"))))
    assert tap.dropped == {"tap behind": 1}
    tap.start()
    wait_until(lambda: tap.failure is not None, 10.0, "the write to fail")
    tap.stop()
    assert [f.errno for f in failures] == [28]


def test_the_last_line_says_what_was_dropped_by_reason_and_nothing_when_none_was() -> None:
    assert ended_line("fleet record: 3 messages in a.mcap", Counter()) == (
        "fleet record: 3 messages in a.mcap"
    )
    dropped = Counter({"not JSON": 2, "delete": 1})
    assert ended_line("done", dropped) == "done; 3 dropped: {'not JSON': 2, 'delete': 1}"
