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

Bus callbacks only queue what they hear; one thread decodes and logs to the channels.
A payload that is not JSON, too large or nested too deep, is dropped, counted and logged
once per key; so is a sample beyond the queue's limit, or a key beyond `MAX_CHANNELS`.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import foxglove
from foxglove.channels import GeoJsonChannel, LocationFixChannel, LogChannel, SceneUpdateChannel
from foxglove.messages import Color, GeoJson, LocationFix, Timestamp

from fleet.mission import key_registry as reg
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.mission.messages import AssignmentReport, MissionAbort, MissionTargets, TargetOutcome
from fleet.recording import channels
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusSample, Declaration
from ground.foxglove_live import map_layers, scene
from ground.foxglove_live.map_layers import Fix, MissionMap

log = logging.getLogger(__name__)

DEFAULT_STATE_EVERY_S = 1.0
#: How often the mission's GeoJSON is sent again while nothing changes.
MAP_EVERY_S = 1.0
#: How often the 3D scene is sent at most as the aircraft move.
SCENE_EVERY_S = 0.25
#: Samples waiting beyond this are dropped (and counted), not queued.
QUEUE_LIMIT = 10_000
#: Channels at most: keys beyond it (a publisher making up keys) are dropped and counted.
MAX_CHANNELS = 4096

_MISSION_KINDS: dict[reg.KeySpec, type[Any]] = {
    reg.TARGETS: MissionTargets,
    reg.ASSIGNMENT: AssignmentReport,
    reg.REPLAN: AssignmentReport,
    reg.OUTCOME: TargetOutcome,
    reg.ABORT: MissionAbort,
}


@dataclass(frozen=True)
class Heard:
    key: str
    payload: bytes
    time_ns: int


#: Queued by the ticker: send the map again.
_TICK = Heard("", b"", 0)


class FoxgloveBridge:
    """Subscribes on `bus` and logs what it hears to channels of `context`.

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
        self._bus = bus
        self._context = context
        self._space = key_space
        self._state_every_s = state_every_s
        self._queue: queue.Queue[Heard | None] = queue.Queue()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._declared: list[Declaration] = []
        # Each channel with its pattern, by topic (by UAV for the fixes): a channel's spec
        # is derived once, when its key is first heard, never per message.
        self._json: dict[str, tuple[foxglove.Channel, str]] = {}
        self._fixes: dict[int, tuple[LocationFixChannel, str]] = {}
        self._map_channel: GeoJsonChannel | None = None
        self._scene_channel: SceneUpdateChannel | None = None
        self._log_channel: LogChannel | None = None
        self._scene = scene.Scene()
        self._scene_sent = 0.0
        self._bad_keys: set[str] = set()
        self._lock = threading.Lock()
        self.map = MissionMap()
        #: Messages logged, per channel pattern (the map's topic for the GeoJSON).
        self.published: Counter[str] = Counter()
        #: Dropped, per reason.
        self.dropped: Counter[str] = Counter()

    # ---- life cycle ---------------------------------------------------------------------------
    def start(self) -> None:
        # With details: a deleted key is told apart from an empty put (`_on_sample`).
        self._declared.append(
            self._bus.subscribe(self._space.everything, self._on_sample, details=True)
        )
        self._declared.append(self._bus.subscribe_presence(self._space.all_alive, self._on_alive))
        self._threads = [
            threading.Thread(target=self._publish_loop, name="foxglove-publish"),
            threading.Thread(target=self._tick_loop, name="foxglove-ticker"),
        ]
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        for declared in self._declared:
            declared.undeclare()
        self._declared.clear()
        self._stop.set()
        self._queue.put(None)
        for thread in self._threads:
            thread.join()
        self._threads.clear()

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

    # ---- the bus's threads: only queue ----------------------------------------------------------
    def _drop(self, reason: str) -> None:
        with self._lock:
            self.dropped[reason] += 1

    def _enqueue(self, heard: Heard) -> None:
        if self._queue.qsize() >= QUEUE_LIMIT:
            self._drop("publisher behind")
            return
        self._queue.put(heard)

    def _on_sample(self, sample: BusSample) -> None:
        if sample.deleted:
            self._drop("delete")
            return
        self._enqueue(Heard(sample.key, sample.payload, time.time_ns()))

    def _on_alive(self, key: str, alive: bool) -> None:
        payload = b'{"alive":true}' if alive else b'{"alive":false}'
        self._enqueue(Heard(key, payload, time.time_ns()))

    def _tick_loop(self) -> None:
        """The map every MAP_EVERY_S at least, the state query every `state_every_s`."""
        state_every = self._state_every_s
        every = min(state_every, MAP_EVERY_S) if state_every > 0 else MAP_EVERY_S
        next_query = time.monotonic()
        while not self._stop.wait(every):
            if state_every > 0 and time.monotonic() >= next_query:
                next_query = time.monotonic() + state_every
                try:
                    self._bus.get(self._space.all_state, self._on_sample, timeout=state_every)
                except Exception as error:  # the session closing under it: try again later
                    log.warning("state query failed: %s", error)
            self._enqueue(_TICK)

    # ---- the publishing thread ------------------------------------------------------------------
    def _publish_loop(self) -> None:
        last_map = 0.0
        while True:
            heard = self._queue.get()
            if heard is None:
                break
            try:
                if heard is not _TICK:
                    self._publish(heard)
                elif time.monotonic() - last_map >= MAP_EVERY_S / 2:
                    self._send_map()
                    last_map = time.monotonic()
            except Exception:  # a bug here must not end the server: log it, go on
                log.exception("cannot publish %s", heard.key or "the map")
                self._drop("error")

    def _publish(self, heard: Heard) -> None:
        try:
            value = bus_codec.decode_json(heard.payload, Any, heard.key)
        except bus_codec.BadMessage as error:
            reason = error.reason
            self._drop("not JSON" if reason is bus_codec.DropReason.INVALID else str(reason))
            self._log_bad_once(heard.key, str(error))
            return
        entry = self._json.get(heard.key) or self._json_channel(heard.key)
        if entry is None:
            return
        channel, pattern = entry
        channel.log(heard.payload, log_time=heard.time_ns)
        self._count(pattern)
        if pattern.endswith(f"/{reg.TELEMETRY.leaf}"):
            self._publish_fix(heard, value)
        elif pattern.endswith(f"/{reg.STATUS.leaf}"):
            self._publish_log(heard, value)
        else:
            self._follow_mission(heard)

    def _log_bad_once(self, key: str, why: str) -> None:
        if key not in self._bad_keys and len(self._bad_keys) < MAX_CHANNELS:
            self._bad_keys.add(key)
            log.warning("not shown: %s; further ones counted", why)

    def _count(self, pattern: str) -> None:
        with self._lock:
            self.published[pattern] += 1

    def _json_channel(self, key: str) -> tuple[foxglove.Channel, str] | None:
        """A new channel for `key`; None (counted) past MAX_CHANNELS."""
        if len(self._json) >= MAX_CHANNELS:
            self._drop("too many keys")
            return None
        spec = channels.heard_channel(self._space.prefix, key)
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

    def _publish_fix(self, heard: Heard, telemetry: object) -> None:
        try:
            uav = uav_id_of(heard.key)
        except (ValueError, IndexError):
            return
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

    def _publish_log(self, heard: Heard, status: object) -> None:
        try:
            uav = uav_id_of(heard.key)
        except (ValueError, IndexError):
            return
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

    def _follow_mission(self, heard: Heard) -> None:
        parsed = self._space.parse(heard.key)
        kind = None if parsed is None else _MISSION_KINDS.get(parsed.spec)
        if kind is None:
            return
        try:
            message = bus_codec.decode(heard.payload, kind, heard.key)
        except bus_codec.BadMessage as error:
            self._drop(str(error.reason))
            self._log_bad_once(heard.key, str(error))
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
