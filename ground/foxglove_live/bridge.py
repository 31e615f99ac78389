"""The fleet's bus onto a Foxglove context's channels (the server of `fleet foxglove`).

The channels are those `fleet record` writes, with the same topics and schema names
(`fleet.recording.channels`), so a live view and a recording opened in Foxglove show
the same topics:

* every sample put under `{prefix}/**`, on a channel per key, as the JSON it carries;
* each UAV's state (`uav/*/state`, never published), by a query every `state_every_s`;
* each UAV's liveliness token appearing or going (`uav/{id}/alive`);
* a `foxglove.LocationFix` per telemetry (`uav/{id}/location_fix`). The recorder writes
  it as JSON; here it is the SDK's own LocationFix (protobuf), which carries a heading
  and a colour too.

Three more topics, live only:

* `{prefix}/map/targets`, the current mission as GeoJSON (`map_layers`), sent when the
  mission changes and every second, so a client that connects late sees it;
* `{prefix}/scene`, the fleet in 3D as a `foxglove.SceneUpdate` (`scene`): aircraft,
  targets, tours and no-fly zones, sent with the map and at most every `SCENE_EVERY_S`
  as the aircraft move;
* `{prefix}/log`, every UAV's status text as a `foxglove.Log`, for the Log panel.

What it hears is what `fleet record` hears, by the same tap (fleet.recording.bus_tap):
bus callbacks only queue, one worker decodes and logs to the channels. A payload that
is not JSON, too large or nested too deep, is dropped, counted and logged once per key;
so is a sample beyond the queue's limit, or a key beyond `MAX_CHANNELS`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from typing import Any

import foxglove
from foxglove.channels import GeoJsonChannel, LocationFixChannel, LogChannel, SceneUpdateChannel
from foxglove.messages import Color, GeoJson, LocationFix, Timestamp

from fleet.mission import key_registry as reg
from fleet.mission.key_space import KeySpace, ParsedKey
from fleet.mission.messages import AssignmentReport, MissionAbort, MissionTargets, TargetOutcome
from fleet.recording import channels
from fleet.recording.bus_tap import DEFAULT_STATE_EVERY_S, BusTap, Heard
from fleet.recording.channels import ChannelSpec
from fleet.transport import bus_codec
from fleet.transport.bus import Bus
from ground.foxglove_live import map_layers, scene
from ground.foxglove_live.map_layers import Fix, MissionMap

log = logging.getLogger(__name__)

__all__ = ["DEFAULT_STATE_EVERY_S", "FoxgloveBridge", "location_fix"]

#: How often the mission's GeoJSON is sent again while nothing changes.
MAP_EVERY_S = 1.0
#: How often the 3D scene is sent at most as the aircraft move.
SCENE_EVERY_S = 0.25
#: Samples waiting beyond this are dropped (and counted), not queued.
QUEUE_LIMIT = 10_000
#: Channels at most: keys beyond it (a publisher making up keys) are dropped and counted.
MAX_CHANNELS = 4096
#: The tap's worker takes what is queued this often, seconds: a live view's latency.
BATCH_S = 0.05

_MISSION_KINDS: dict[reg.KeySpec, type[Any]] = {
    reg.TARGETS: MissionTargets,
    reg.ASSIGNMENT: AssignmentReport,
    reg.REPLAN: AssignmentReport,
    reg.OUTCOME: TargetOutcome,
    reg.ABORT: MissionAbort,
}


def _uav_number(parsed: ParsedKey) -> int | None:
    """The UAV a key is of, as a number; None if the key spells none (keys are not
    checked on the way in)."""
    try:
        return int(parsed.uav or "")
    except ValueError:
        return None


class FoxgloveBridge:
    """Logs what a tap on `bus` hears to channels of `context`.

    `start()` returns once the subscriptions are declared; `stop()` undeclares them and
    logs what is still queued.
    """

    def __init__(
        self,
        bus: Bus,
        context: foxglove.Context,
        key_space: KeySpace,
        *,
        state_every_s: float = DEFAULT_STATE_EVERY_S,
    ) -> None:
        self._context = context
        self._space = key_space
        # Each channel with its pattern, by topic (by UAV for the fixes): a channel's spec
        # is derived once, when its key is first heard, never per message.
        self._json: dict[str, tuple[foxglove.Channel, str]] = {}
        self._fixes: dict[int, tuple[LocationFixChannel, str]] = {}
        self._map_channel: GeoJsonChannel | None = None
        self._last_map = 0.0
        self._scene_channel: SceneUpdateChannel | None = None
        self._log_channel: LogChannel | None = None
        self._scene = scene.Scene()
        self._scene_sent = 0.0
        self._lock = threading.Lock()
        self.map = MissionMap()
        #: Messages logged, per channel pattern (the map's topic for the GeoJSON).
        self.published: Counter[str] = Counter()
        self.tap = BusTap(
            bus,
            self,
            key_space,
            state_every_s=state_every_s,
            queue_limit=QUEUE_LIMIT,
            batch_s=min(BATCH_S, MAP_EVERY_S / 2),
            max_channels=MAX_CHANNELS,
            name="publisher",
            refused="not shown",
        )

    @property
    def dropped(self) -> Counter[str]:
        """Dropped, per reason."""
        return self.tap.dropped

    # ---- life cycle ---------------------------------------------------------------------------
    def start(self) -> None:
        self.tap.start()

    def stop(self) -> None:
        self.tap.stop()

    def topics(self) -> dict[str, str]:
        """Each channel's topic and schema name ("" for none), as a client sees them.

        Once stopped: while running, the publishing thread adds channels."""
        found = {topic: channel.schema_name() or "" for topic, (channel, _) in self._json.items()}
        found.update({fix.topic(): channels.LOCATION_FIX for fix, _ in self._fixes.values()})
        if self._map_channel is not None:
            found[self._map_channel.topic()] = GeoJson.get_schema().name
        for extra in (self._scene_channel, self._log_channel):
            if extra is not None:
                found[extra.topic()] = extra.schema_name() or ""
        return found

    # ---- the tap's sink (its worker thread) ---------------------------------------------------
    def keep(self, heard: Heard, spec: ChannelSpec) -> bool:
        return True

    def write(self, heard: Heard, spec: ChannelSpec, value: Any) -> None:
        entry = self._json.get(heard.key) or self._json_channel(heard.key, spec)
        channel, pattern = entry
        channel.log(heard.payload, log_time=heard.time_ns)
        self._count(pattern)
        parsed = self._space.parse(heard.key)
        if parsed is None:
            return
        if parsed.spec in _MISSION_KINDS:
            self._follow_mission(heard, _MISSION_KINDS[parsed.spec])
            return
        uav = _uav_number(parsed)
        if uav is None:
            return
        if parsed.spec is reg.TELEMETRY:
            self._publish_fix(heard, uav, value)
        elif parsed.spec is reg.STATUS:
            self._publish_log(heard, uav, value)

    def tick(self) -> None:
        """The map again, every MAP_EVERY_S at least, so a client that connects late sees it."""
        if time.monotonic() - self._last_map >= MAP_EVERY_S / 2:
            self._send_map()

    def _count(self, pattern: str) -> None:
        with self._lock:
            self.published[pattern] += 1

    def _json_channel(self, key: str, spec: ChannelSpec) -> tuple[foxglove.Channel, str]:
        """A new channel for `key` (the tap bounds how many)."""
        # A key of no known pattern has no schema: named "" as in a recording (the SDK
        # would make up a name for None).
        schema = foxglove.Schema(
            name=spec.schema_name, encoding=channels.SCHEMA_ENCODING, data=spec.schema
        )
        channel = foxglove.Channel(
            spec.topic,
            schema=schema,
            message_encoding=channels.MESSAGE_ENCODING,
            context=self._context,
            metadata=spec.metadata,
        )
        self._json[key] = (channel, spec.pattern)
        return self._json[key]

    def _publish_fix(self, heard: Heard, uav: int, telemetry: object) -> None:
        fix = map_layers.fix_of(telemetry, uav, heard.time_ns)
        if fix is None:
            return
        entry = self._fixes.get(uav)
        if entry is None:
            spec = channels.location_channel(self._space.prefix, uav)
            channel = LocationFixChannel(spec.topic, metadata=spec.metadata, context=self._context)
            entry = self._fixes[uav] = (channel, spec.pattern)
        channel, pattern = entry
        channel.log(location_fix(fix), log_time=heard.time_ns)
        self._count(pattern)
        self.map.on_fix(fix)
        if time.monotonic() - self._scene_sent >= SCENE_EVERY_S:
            self._send_scene()

    def _publish_log(self, heard: Heard, uav: int, status: object) -> None:
        entry = scene.status_log(status, uav, heard.time_ns)
        if entry is None:
            return
        if self._log_channel is None:
            topic = scene.log_topic(self._space.prefix)
            self._log_channel = LogChannel(topic, context=self._context)
        self._log_channel.log(entry, log_time=heard.time_ns)
        self._count(self._log_channel.topic())

    def _send_scene(self) -> None:
        now = time.time_ns()
        update = self._scene.update(self.map, now)
        self._scene_sent = time.monotonic()
        if update is None:
            return
        if self._scene_channel is None:
            topic = scene.scene_topic(self._space.prefix)
            self._scene_channel = SceneUpdateChannel(topic, context=self._context)
        self._scene_channel.log(update, log_time=now)
        self._count(self._scene_channel.topic())

    def _follow_mission(self, heard: Heard, kind: type[Any]) -> None:
        try:
            message = bus_codec.decode(heard.payload, kind, heard.key)
        except bus_codec.BadMessage as error:
            self.tap.refuse(heard.key, error, as_json=False)
            return
        if isinstance(message, MissionTargets):
            changed = self.map.on_targets(message)
        elif isinstance(message, AssignmentReport):
            changed = self.map.on_assignment(message)
        elif isinstance(message, TargetOutcome):
            changed = self.map.on_outcome(message)
        else:
            changed = self.map.on_abort(message)
        if changed:
            self._send_map()

    def _send_map(self) -> None:
        self._last_map = time.monotonic()
        self._send_scene()
        if self.map.targets is None:
            return
        if self._map_channel is None:
            topic = map_layers.targets_topic(self._space.prefix)
            self._map_channel = GeoJsonChannel(topic, context=self._context)
        self._map_channel.log(GeoJson(geojson=map_layers.geojson(self.map)))
        self._count(self._map_channel.topic())


def location_fix(fix: Fix) -> LocationFix:
    """The SDK's LocationFix of `fix`."""
    colour = fix.colour
    return LocationFix(
        timestamp=Timestamp(fix.time_ns // 1_000_000_000, fix.time_ns % 1_000_000_000),
        frame_id=fix.frame_id,
        latitude=fix.latitude,
        longitude=fix.longitude,
        altitude=fix.altitude,
        heading=fix.heading_rad,
        color=Color(r=colour.r, g=colour.g, b=colour.b, a=1.0),
    )
