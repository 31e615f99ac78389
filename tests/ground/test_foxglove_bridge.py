"""`fleet foxglove`'s bridge (ground.foxglove_live.bridge) on an in-memory bus: what it
hears goes on the recorder's topics, with the recorder's schema names; hostile input is
dropped and counted. What the channels carry is read back from an MCAP file the SDK
writes from the same context (the WebSocket server is the end-to-end test's)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import foxglove
import msgspec
import pytest
from mcap.reader import make_reader

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, StatusText, Target
from fleet.mission.status_kind import StatusKind
from fleet.recording import channels
from fleet.transport import bus_codec
from fleet.transport.bus import BusSample, SampleCallback
from fleet.transport.memory import MemoryBus, MemoryNetwork
from ground.foxglove_live import bridge as bridge_module
from ground.foxglove_live.bridge import FoxgloveBridge
from tests.support.link_samples import sample_telemetry
from tests.support.waiting import wait_until

SPACE = KeySpace("fleet")
TARGETS = MissionTargets(5, (74,), (Target(42.36, -71.09, 120.0), Target(42.37, -71.1, 90.0)))


class Live:
    """A bridge on a memory bus, its channels recorded by the SDK to `path`."""

    def __init__(self, path: Path) -> None:
        self.network = MemoryNetwork()
        self.fleet: MemoryBus = self.network.bus()
        self.ground = self.network.bus()
        self.context = foxglove.Context()
        self.path = path
        self.writer = foxglove.open_mcap(path, context=self.context)
        self.bridge = FoxgloveBridge(self.ground, self.context, SPACE, state_every_s=0)

    def stopped(self) -> dict[str, list[tuple[str, str, bytes]]]:
        """Stop; each topic's (schema name, schema encoding, message) as written."""
        self.bridge.stop()
        self.writer.close()
        found: dict[str, list[tuple[str, str, bytes]]] = {}
        with open(self.path, "rb") as f:
            for schema, channel, message in make_reader(f).iter_messages():
                name, encoding = (schema.name, schema.encoding) if schema else ("", "")
                found.setdefault(channel.topic, []).append((name, encoding, message.data))
        return found


@pytest.fixture
def live(tmp_path: Path) -> Iterator[Live]:
    opened = Live(tmp_path / "live.mcap")
    opened.bridge.start()
    try:
        yield opened
    finally:
        opened.bridge.stop()
        opened.fleet.close()
        opened.ground.close()


def protobuf_string(data: bytes) -> str:
    """Field 1 of a protobuf message holding one string (foxglove.GeoJSON)."""
    assert data[0] == 0x0A
    length, shift, at = 0, 0, 1
    while True:
        byte = data[at]
        length |= (byte & 0x7F) << shift
        at, shift = at + 1, shift + 7
        if not byte & 0x80:
            break
    return data[at : at + length].decode()


def test_the_fleet_goes_on_the_recorders_topics(live: Live) -> None:
    telemetry = bus_codec.encode(sample_telemetry())
    status = bus_codec.encode(StatusText("ready", StatusKind.INFO))
    token = live.fleet.declare_token(SPACE.alive(74))
    for _ in range(3):
        live.fleet.put(SPACE.telemetry(74), telemetry)
    live.fleet.put(SPACE.status(74), status)
    live.fleet.put(SPACE.mission_targets(5), bus_codec.encode(TARGETS))
    report = AssignmentReport(5, 74, 1, {74: 1}, (0,), (74,), "digest")
    live.fleet.put(SPACE.mission_assignment(5, 74), bus_codec.encode(report))
    token.undeclare()
    written = live.stopped()
    topics = live.bridge.topics()

    fix_topic = channels.location_channel("fleet", 74).topic
    assert topics == {
        SPACE.alive(74): channels.LIVELINESS,
        SPACE.telemetry(74): "Telemetry",
        fix_topic: channels.LOCATION_FIX,
        SPACE.status(74): "StatusText",
        SPACE.mission_targets(5): "MissionTargets",
        SPACE.mission_assignment(5, 74): "AssignmentReport",
        "fleet/map/targets": "foxglove.GeoJSON",
        # Live only: the fleet in 3D and the status texts for the Log panel.
        "fleet/scene": "foxglove.SceneUpdate",
        "fleet/log": "foxglove.Log",
    }
    # Every bus key on the recorder's channel: its topic, schema name and the JSON as put.
    for key in (SPACE.telemetry(74), SPACE.status(74), SPACE.mission_targets(5)):
        spec = channels.channel_for(key)
        assert {(name, encoding) for name, encoding, _ in written[key]} == {
            (spec.schema_name, channels.SCHEMA_ENCODING)
        }
    assert [data for *_, data in written[SPACE.telemetry(74)]] == [telemetry] * 3
    assert [data for *_, data in written[SPACE.status(74)]] == [status]
    alive = [msgspec.json.decode(data) for *_, data in written[SPACE.alive(74)]]
    assert alive == [{"alive": True}, {"alive": False}]
    assert [(n, e) for n, e, _ in written[fix_topic]] == [(channels.LOCATION_FIX, "protobuf")] * 3
    assert live.bridge.published[channels.location_channel("fleet", 74).pattern] == 3

    # The map: the targets, then 74 assigned to target 1.
    maps = [msgspec.json.decode(protobuf_string(data)) for *_, data in written["fleet/map/targets"]]
    last: dict[str, Any] = maps[-1]
    points = [f for f in last["features"] if f["geometry"]["type"] == "Point"]
    assert [p["properties"]["state"] for p in points] == ["unassigned", "assigned"]
    assert [p["geometry"]["coordinates"] for p in points] == [[-71.09, 42.36], [-71.1, 42.37]]
    assert live.bridge.dropped == {}


def test_hostile_input_is_dropped_and_counted(live: Live, caplog: pytest.LogCaptureFixture) -> None:
    live.fleet.put(SPACE.telemetry(74), b"\xff not json")
    live.fleet.put(SPACE.telemetry(74), b"\xff not json either")
    live.fleet.put(SPACE.status(74), b"[" * 5000 + b"]" * 5000)
    live.fleet.put(SPACE.telemetry(75), b"x" * (bus_codec.MAX_PAYLOAD_BYTES + 1))
    # JSON, but not the mission's targets: shown as heard, not drawn.
    live.fleet.put(SPACE.mission_targets(6), b'{"mission": "six"}')
    live.bridge.tap.on_sample(BusSample(SPACE.status(74), b"", deleted=True))
    written = live.stopped()
    assert live.bridge.dropped == {
        "not JSON": 2,
        "too_deep": 1,
        "too_large": 1,
        "invalid": 1,
        "delete": 1,
    }
    assert list(written) == [SPACE.mission_targets(6)]
    warnings = [r.message for r in caplog.records if "not shown" in r.message]
    assert len(warnings) == 4  # once per key: the second bad telemetry is only counted


def test_keys_beyond_the_limit_are_dropped(live: Live, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(live.bridge.tap, "max_channels", 3)
    for index in range(5):
        live.fleet.put(SPACE.waypoint(74, index), b"{}")
    live.stopped()
    assert len(live.bridge.topics()) == 3
    assert live.bridge.dropped == {"too many keys": 2}


def test_a_token_that_is_no_uavs_is_shown_as_heard_without_a_schema(live: Live) -> None:
    live.fleet.declare_token("fleet/uav/any/alive")
    written = live.stopped()
    assert [(name, data) for name, _, data in written["fleet/uav/any/alive"]] == [
        ("", b'{"alive":true}')
    ]
    assert live.bridge.topics() == {"fleet/uav/any/alive": ""}


def test_telemetry_and_status_of_a_uav_that_is_no_number_have_no_fix_and_no_log(
    live: Live,
) -> None:
    """Keys are not checked on the way in: such a UAV's keys are shown as heard, no more."""
    live.fleet.put("fleet/uav/any/telemetry", bus_codec.encode(sample_telemetry()))
    live.fleet.put("fleet/uav/any/status", bus_codec.encode(StatusText("ready", StatusKind.INFO)))
    live.stopped()
    assert set(live.bridge.topics()) == {"fleet/uav/any/telemetry", "fleet/uav/any/status"}
    assert live.bridge.dropped == {}


class QueryProbe(MemoryBus):
    """A ground bus whose queries are noted (and fail with `error`, if given)."""

    def __init__(self, network: MemoryNetwork, error: Exception | None = None) -> None:
        super().__init__(network)
        self.selectors: list[str] = []
        self.error = error

    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        self.selectors.append(selector)
        if self.error is not None:
            raise self.error


def maps_sent(ground: QueryProbe, state_every_s: float, count: int) -> None:
    """Put a mission on a bridge over `ground`; wait until its map was sent `count` times
    (once when heard, then at the ticks)."""
    fleet = ground.network.bus()
    bridge = FoxgloveBridge(ground, foxglove.Context(), SPACE, state_every_s=state_every_s)
    bridge.start()
    try:
        fleet.put(SPACE.mission_targets(5), bus_codec.encode(TARGETS))
        wait_until(lambda: bridge.published["fleet/map/targets"] >= count, 10.0, f"{count} maps")
    finally:
        bridge.stop()


def test_the_map_is_sent_again_even_when_state_queries_fail(
    caplog: pytest.LogCaptureFixture,
) -> None:
    ground = QueryProbe(MemoryNetwork(), RuntimeError("session closing"))
    maps_sent(ground, 0.05, 3)
    assert len(ground.selectors) >= 2
    assert any("state query failed: session closing" in r.message for r in caplog.records)


def test_a_slow_state_query_does_not_slow_the_map(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bridge_module, "MAP_EVERY_S", 0.05)
    ground = QueryProbe(MemoryNetwork())
    maps_sent(ground, 30.0, 4)
    assert ground.selectors == [SPACE.all_state]  # once, at the first tick
