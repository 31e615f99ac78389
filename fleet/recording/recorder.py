"""Record the fleet's key space from Zenoh into MCAP (`fleet record`).

What is recorded:

* every sample put under the expression (default `{prefix}/**`), on a channel per key;
* each UAV's state (`{prefix}/uav/*/state`, a queryable that is never published), by a
  query every `state_every_s` (in a fleet of more than 10, every N / 10 s), so the
  mission phases are in the recording;
* each UAV's liveliness token appearing or going (`.../alive`, `{"alive": bool}`);
* a `foxglove.LocationFix` from each UAV's telemetry, for Foxglove's map, one every
  `fix_every_s` per UAV (1 s by default; 0: one per telemetry).

Telemetry is recorded at most every `telemetry_every_s` per key (5 Hz; 0: every one;
`fleet.recording.thinning`): the live rate is 20 Hz.

Log time is the Zenoh timestamp the router stamped on the sample where there is one,
else the time it was received. Zenoh delivers samples on its own threads, which only
append them to a queue (no hand-off to a Python thread per sample, no wake-up); one
writer thread owns the file and takes everything queued every `BATCH_S`, so a slow disk
never blocks Zenoh and a fleet's thousands of samples a second cost a few wake-ups.
A payload that is not JSON, or too large or nested too deep to decode safely, is
dropped, counted and logged (once per key).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import msgspec
import zenoh

from fleet.mission.key_space import DEFAULT_SPACE, KeySpace, uav_id_of
from fleet.recording import channels
from fleet.recording.channels import ChannelSpec
from fleet.recording.streams import StreamCounts
from fleet.recording.thinning import DEFAULT_TELEMETRY_EVERY_S, TelemetryThinning
from fleet.recording.writer import McapSink
from fleet.transport import bus_codec
from fleet.transport.bus import Declaration
from fleet.transport.bus_codec import DropReason
from fleet.transport.zenoh_bus import direct

log = logging.getLogger(__name__)
#: How many keys' refusals are logged (each once); the rest are only counted.
MAX_BAD_KEYS_LOGGED = 1000
#: How many keys of no known pattern get a channel; samples on further ones are counted.
MAX_UNKNOWN_KEYS = 1000

DEFAULT_STATE_EVERY_S = 1.0
#: UAV states asked for a second, at most: each is a query every onboard wakes up to
#: answer with its whole state (~2 KB); 50 a second cost ~4 % of a core at N = 50.
MAX_STATES_PER_S = 10.0
#: The line `fleet record` prints once it listens (the launcher waits for it).
READY_LINE = "fleet record: recording"
#: Samples waiting for the writer beyond this are dropped (and counted), not queued.
QUEUE_LIMIT = 100_000
#: Zenoh's own queue in the router's process (`in_router`): a ring whose every slot is
#: touched as it turns (100,000 held 25 MB), 10-20 s of a 50-100-UAV fleet's samples.
RING_LIMIT = 20_000
#: Keys whose channel is remembered, and UAVs whose last map fix is: past these, a
#: peer putting on ever new keys costs a lookup per sample, never memory.
MAX_CACHED = 10_000
#: The writer takes what is queued this often, seconds: a batch, not a wake-up a sample.
BATCH_S = 0.1
#: One map fix per UAV this often, seconds: a track point every ~20 m at cruise speed.
DEFAULT_FIX_EVERY_S = 1.0


@dataclass(frozen=True)
class Heard:
    """One thing heard on the bus, waiting to be written."""

    key: str
    payload: bytes
    time_ns: int


def sample_time_ns(timestamp: zenoh.Timestamp | None) -> int:
    """The Zenoh timestamp in ns since the epoch, or now when the sample has none."""
    if timestamp is None:
        return time.time_ns()
    moment: datetime = timestamp.get_time()
    return int(moment.timestamp()) * 1_000_000_000 + moment.microsecond * 1000


def state_period(every_s: float, uavs: int) -> float:
    """How long until the next state query, after `uavs` answered the last one: `every_s`,
    or longer in a large fleet, so the fleet answers at most MAX_STATES_PER_S a second."""
    return max(every_s, uavs / MAX_STATES_PER_S)


@dataclass
class RecorderStats:
    recorded: Counter[str] = field(default_factory=Counter)  #: per pattern
    dropped: Counter[str] = field(default_factory=Counter)  #: per reason


class Recorder:
    """Subscribes to `expr` (and queries states) on `session`, writing into `sink`.

    `start()` returns once every subscription is declared; `stop()` undeclares them,
    writes what is queued and finishes the file.
    """

    def __init__(
        self,
        session: zenoh.Session,
        sink: McapSink,
        *,
        expr: str | None = None,
        key_space: KeySpace = DEFAULT_SPACE,
        state_every_s: float = DEFAULT_STATE_EVERY_S,
        on_failure: threading.Event | None = None,
        fix_every_s: float = DEFAULT_FIX_EVERY_S,
        in_router: bool = False,
        telemetry_every_s: float = DEFAULT_TELEMETRY_EVERY_S,
    ) -> None:
        self._session = session
        self._in_router = in_router
        self._ring: zenoh.Subscriber[zenoh.Handler[zenoh.Sample]] | None = None
        self.sink = sink
        self.prefix = key_space.prefix
        self.expr = expr or f"{self.prefix}/**"
        self._state_every_s = state_every_s
        self._fix_every_ns = round(fix_every_s * 1e9)
        self.thinning = TelemetryThinning(telemetry_every_s)
        # Appended on Zenoh's threads, taken on the writer's (deque's ends are atomic).
        self._queue: deque[Heard | zenoh.Sample] = deque()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._declared: list[Declaration] = []
        self._bad_keys: set[str] = set()
        self._unknown_keys: set[str] = set()
        self._last_fix_ns: dict[int, int] = {}
        self._specs: dict[str, ChannelSpec] = {}  # by key
        self._fix_specs: dict[int, ChannelSpec] = {}  # by UAV
        self.stats = RecorderStats()
        #: Samples recorded per UAV and channel; whose telemetry stopped (`fleet up` asks).
        self.streams = StreamCounts(self.prefix)
        #: Why writing stopped (the disk is full, ...); `on_failure` is set then.
        self.failure: str | None = None
        self._on_failure = on_failure

    # ---- life cycle ----------------------------------------------------------------------
    def start(self) -> None:
        """Open the file, then subscribe; OSError or zenoh.ZError (a bad expression) if not."""
        self.sink.open()
        if self._in_router:
            # The router's own session: a Python callback would hold its routing threads
            # on this process's GIL. Zenoh queues the samples itself (the oldest go past
            # RING_LIMIT, uncounted: a writer that far behind has a disk that stalls)
            # and the writer takes them.
            self._ring = self._session.declare_subscriber(
                self.expr, zenoh.handlers.RingChannel(RING_LIMIT)
            )
            self._declared.append(self._ring)
        else:
            self._declared.append(
                self._session.declare_subscriber(self.expr, direct(self._on_sample))
            )
        alive = f"{self.prefix}/uav/*/{channels.ALIVE_LEAF}"
        self._declared.append(
            self._session.liveliness().declare_subscriber(alive, self._on_alive, history=True)
        )
        self._threads = [threading.Thread(target=self._write_loop, name="mcap-writer")]
        if self._state_every_s > 0 and self._covers_state():
            self._threads.append(threading.Thread(target=self._poll_states, name="state-poll"))
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        # Nothing more is heard, then the writer takes what is queued and ends; Zenoh's
        # ring goes with its subscriber, so with one the writer ends first (the fleet
        # has stopped by then: next to nothing is lost between the two).
        if self._ring is not None:
            self._end_writer()
        for declared in self._declared:
            declared.undeclare()
        self._declared.clear()
        self._ring = None
        self._end_writer()
        if self.failure is None:
            with contextlib.suppress(OSError):  # heard after the writer ended (a token)
                self._write_queued()
        with contextlib.suppress(OSError):  # already reported as the failure
            self.sink.close()

    def _end_writer(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self._threads.clear()

    def _covers_state(self) -> bool:
        probe = f"{self.prefix}/uav/0/{channels.STATE_LEAF}"
        return channels.matches(self.expr, probe)

    # ---- Zenoh threads -------------------------------------------------------------------
    def _enqueue(self, heard: Heard | zenoh.Sample) -> None:
        if len(self._queue) >= QUEUE_LIMIT:
            self.stats.dropped["writer behind"] += 1
            return
        self._queue.append(heard)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        # On Zenoh's thread: queued as it is; the writer reads it (and drops a delete).
        self._enqueue(sample)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        alive = sample.kind == zenoh.SampleKind.PUT
        payload = b'{"alive":true}' if alive else b'{"alive":false}'
        self._enqueue(Heard(str(sample.key_expr), payload, sample_time_ns(sample.timestamp)))

    def _poll_states(self) -> None:
        selector = f"{self.prefix}/uav/*/{channels.STATE_LEAF}"
        period = self._state_every_s
        while not self._stop.wait(period):
            try:
                replies = list(self._session.get(selector, timeout=self._state_every_s))
            except zenoh.ZError as error:
                log.warning("state query failed: %s", error)
                continue
            period = state_period(self._state_every_s, len(replies))
            for reply in replies:
                if reply.ok is not None:
                    sample = reply.ok
                    self._enqueue(
                        Heard(
                            str(sample.key_expr),
                            sample.payload.to_bytes(),
                            sample_time_ns(sample.timestamp),
                        )
                    )

    # ---- the writer thread ---------------------------------------------------------------
    def _write_loop(self) -> None:
        try:
            self._drain()
        except OSError as error:
            self.failure = f"cannot write {self.sink.path}: {error.strerror or error}"
            log.error("%s; recording stopped", self.failure)
            if self._on_failure is not None:
                self._on_failure.set()

    def _drain(self) -> None:
        batch_s = min(BATCH_S, self.sink.flush_every_s / 2)
        while not self._stop.wait(batch_s):
            self._write_queued()
            self.sink.flush_if_due()
        # Whatever arrived before the subscriptions went is written too.
        self._write_queued()

    def _write_queued(self) -> None:
        queued = self._queue
        for _ in range(len(queued)):  # bounded: what is there now; the rest next time
            item = queued.popleft()
            if isinstance(item, Heard):
                self._write(item)
            else:
                self._write_sample(item)
        ring = self._ring
        if ring is not None:
            for _ in range(RING_LIMIT):
                try:
                    sample = ring.try_recv()
                except zenoh.ZError:  # the session closed under the recorder
                    break
                if sample is None:
                    break
                self._write_sample(sample)

    def _write_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            self.stats.dropped["delete"] += 1
            return
        key = str(sample.key_expr)
        self._write(Heard(key, sample.payload.to_bytes(), sample_time_ns(sample.timestamp)))

    def _spec(self, key: str) -> ChannelSpec:
        spec = self._specs.get(key)
        if spec is None:
            spec = channels.channel_for(key)
            if spec.topic.endswith(f"/{channels.ALIVE_LEAF}"):
                # Not a UAV's token: recorded as it is, without a schema.
                with contextlib.suppress(ValueError, IndexError):
                    spec = channels.alive_channel(self.prefix, uav_id_of(key))
            if len(self._specs) < MAX_CACHED:
                self._specs[key] = spec
        return spec

    def _write(self, heard: Heard) -> None:
        spec = self._spec(heard.key)
        if not self.thinning.keep(heard.key, spec.pattern, heard.time_ns):
            return
        try:
            # Any JSON, but not too large or deep to decode safely (bus_codec's limits).
            value = bus_codec.decode_json(heard.payload, Any, heard.key)
        except bus_codec.BadMessage as error:
            reason = error.reason
            self.stats.dropped["not JSON" if reason is DropReason.INVALID else str(reason)] += 1
            # Logged once per key, for a bounded number of keys: a flood on ever new keys
            # is counted, not remembered.
            if heard.key not in self._bad_keys and len(self._bad_keys) < MAX_BAD_KEYS_LOGGED:
                self._bad_keys.add(heard.key)
                log.warning("not recorded: %s; further ones counted", error)
            return
        if not spec.schema_name and spec.topic not in self._unknown_keys:
            # A key of no known pattern is a channel of its own; a peer writing on ever new
            # keys (any UAV may, under its own tree) must not grow the recording's channel
            # table and counters without bound.
            if len(self._unknown_keys) >= MAX_UNKNOWN_KEYS:
                self.stats.dropped["too many unknown keys"] += 1
                return
            self._unknown_keys.add(spec.topic)
        self.sink.write(spec, heard.payload, heard.time_ns, heard.time_ns)
        self.stats.recorded[spec.pattern] += 1
        self.streams.heard(heard.key, value)
        if spec.pattern.endswith("/telemetry") and isinstance(value, dict):
            self._write_fix(heard, value)

    def _write_fix(self, heard: Heard, telemetry: dict[str, object]) -> None:
        try:
            uav = uav_id_of(heard.key)
        except (ValueError, IndexError):
            return
        last = self._last_fix_ns.get(uav)
        if last is not None and 0 <= heard.time_ns - last < self._fix_every_ns:
            return
        fix = channels.location_fix(telemetry, uav, heard.time_ns)
        if fix is None:
            return
        if last is None and len(self._last_fix_ns) >= MAX_CACHED:
            return  # a peer's flood of UAV ids: their telemetry is recorded, not mapped
        self._last_fix_ns[uav] = heard.time_ns
        spec = self._fix_specs.get(uav)
        if spec is None:
            spec = self._fix_specs[uav] = channels.location_channel(self.prefix, uav)
        self.sink.write(spec, msgspec.json.encode(fix), heard.time_ns, heard.time_ns)
        self.stats.recorded[spec.pattern] += 1
