"""One tap on the fleet's bus for the programs that show or keep all of it: `fleet record`
(fleet.recording.recorder, into MCAP) and `fleet foxglove` (ground.foxglove_live.bridge,
to Foxglove's channels). The tap hears; a `TapSink` writes.

What the tap hears, on a bus (`fleet.transport.bus.Bus`):

* every sample put under `expr` (default `{prefix}/**`), each on its key's channel
  (`fleet.recording.channels.heard_channel`: the same topic, schema and pattern in a
  recording and in a live view);
* each UAV's liveliness token appearing or going (`uav/{id}/alive`, `{"alive": bool}`);
* each UAV's state (`uav/*/state`, a queryable never published), by a query every
  `state_every_s` (in a fleet of more than 10, every N / 10 s: `state_period`).

Bus callbacks only queue (no decoding, no wake-up); with `ring_limit` the samples wait in
the bus's own ring instead (`Bus.subscribe_ring`: on the router's own session, no
Python runs on its routing threads). One worker thread takes everything queued every
`batch_s`, and for each sample finds its channel, asks the sink whether it wants it
(`keep`: thinning, before any decoding), decodes it as JSON within the bus codec's
limits, and hands it to the sink (`write`); after each batch the sink gets `tick`.

A sample's time is the router's timestamp where the bus has one, else when it was heard.
Refused, counted in `dropped` by reason and logged once per key (for a bounded number of
keys): a payload that is not JSON, too large or nested too deep; a delete; a sample
beyond the queue's limit; a key beyond `max_channels`, or of no known pattern beyond
`max_unknown_keys`. An OSError from the sink (a full disk) stops the tap (`failure`, and
`on_failure` is called with it); any other exception of the sink is logged and counted,
and the tap goes on.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from fleet.mission.key_space import KeySpace
from fleet.recording import channels
from fleet.recording.channels import ChannelSpec
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusSample, Declaration, RingSubscription

log = logging.getLogger(__name__)

DEFAULT_STATE_EVERY_S = 1.0
#: UAV states asked for a second, at most: each is a query every onboard wakes up to
#: answer with its whole state (~2 KB); 50 a second cost ~4 % of a core at N = 50.
MAX_STATES_PER_S = 10.0
#: The worker takes what is queued this often, seconds: a batch, not a wake-up a sample.
BATCH_S = 0.1
#: How many keys' refusals are logged (each once); the rest are only counted.
MAX_BAD_KEYS_LOGGED = 1000
#: Keys whose channel is remembered: past these, a peer putting on ever new keys costs a
#: lookup per sample, never memory.
MAX_CACHED = 10_000


@dataclass(frozen=True)
class Heard:
    """One thing heard on the bus, waiting for the sink."""

    key: str
    payload: bytes
    time_ns: int


class TapSink(Protocol):
    """Where the tap's samples go: a recording, a live view."""

    def keep(self, heard: Heard, spec: ChannelSpec) -> bool:
        """Whether to take this sample at all (before it is decoded)."""
        ...

    def write(self, heard: Heard, spec: ChannelSpec, value: Any) -> None:
        """A sample on its channel; `value` is its payload decoded (any JSON)."""
        ...

    def tick(self) -> None:
        """After each batch (also when nothing was heard): flush, send what is due."""
        ...


def state_period(every_s: float, uavs: int) -> float:
    """How long until the next state query, after `uavs` answered the last one: `every_s`,
    or longer in a large fleet, so the fleet answers at most MAX_STATES_PER_S a second."""
    return max(every_s, uavs / MAX_STATES_PER_S)


def ended_line(done: str, dropped: Counter[str]) -> str:
    """A tapping program's last line: `done`, then what its tap dropped, by reason."""
    count = sum(dropped.values())
    return done + (f"; {count} dropped: {dict(dropped)}" if count else "")


def alive_payload(alive: bool) -> bytes:
    """What a liveliness token's coming or going is recorded and shown as."""
    return b'{"alive":true}' if alive else b'{"alive":false}'


class BusTap:
    """Hears the fleet on `bus` for `sink`; `start()` returns once every subscription is
    declared, `stop()` undeclares them and hands the sink what is still queued."""

    def __init__(
        self,
        bus: Bus,
        sink: TapSink,
        key_space: KeySpace,
        *,
        expr: str | None = None,
        state_every_s: float = DEFAULT_STATE_EVERY_S,
        queue_limit: int,
        batch_s: float = BATCH_S,
        ring_limit: int | None = None,
        max_channels: int | None = None,
        max_unknown_keys: int | None = None,
        name: str = "tap",
        refused: str = "not taken",
        on_failure: Callable[[OSError], None] | None = None,
    ) -> None:
        self._bus = bus
        self._sink = sink
        self.space = key_space
        self.expr = expr or key_space.everything
        self._state_every_s = state_every_s
        self._queue_limit = queue_limit
        self._batch_s = batch_s
        self._ring_limit = ring_limit
        self._ring: RingSubscription | None = None
        self.max_channels = max_channels
        self.max_unknown_keys = max_unknown_keys
        self._name = name
        self._refused = refused
        self._on_failure = on_failure
        # Appended on the bus's threads, taken on the worker's (deque's ends are atomic).
        self._queue: deque[Heard | BusSample] = deque()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._declared: list[Declaration] = []
        self._specs: dict[str, ChannelSpec] = {}  # by key
        self._channels = 0
        self._unknown_keys: set[str] = set()
        self._bad_keys: set[str] = set()
        self._lock = threading.Lock()
        #: Refused, per reason.
        self.dropped: Counter[str] = Counter()
        #: Why the sink stopped taking samples (the disk is full, ...); None while it takes.
        self.failure: OSError | None = None

    # ---- life cycle ----------------------------------------------------------------------
    def start(self) -> None:
        """Subscribe; what the bus raises for a bad expression goes to the caller."""
        if self._ring_limit is not None:
            self._ring = self._bus.subscribe_ring(self.expr, self._ring_limit)
            self._declared.append(self._ring)
        else:
            # With details: a deleted key is told apart from an empty put, and the
            # router's timestamp comes along.
            self._declared.append(self._bus.subscribe(self.expr, self.on_sample, details=True))
        self._declared.append(self._bus.subscribe_presence(self.space.all_alive, self._on_alive))
        self._threads = [threading.Thread(target=self._work, name=f"{self._name}-worker")]
        if self._state_every_s > 0 and channels.matches(self.expr, self.space.state(0)):
            self._threads.append(threading.Thread(target=self._poll_states, name="state-poll"))
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        # Nothing more is heard, then the worker takes what is queued and ends; the bus's
        # ring goes with its subscription, so with one the worker ends first (the fleet
        # has stopped by then: next to nothing is lost between the two).
        if self._ring is not None:
            self._end_worker()
        for declared in self._declared:
            declared.undeclare()
        self._declared.clear()
        self._ring = None
        self._end_worker()
        if self.failure is None:
            with contextlib.suppress(OSError):  # heard after the worker ended (a token)
                self._take_queued()

    def _end_worker(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self._threads.clear()

    def drop(self, reason: str) -> None:
        with self._lock:
            self.dropped[reason] += 1

    def refuse(self, key: str, error: bus_codec.BadMessage, *, as_json: bool = True) -> None:
        """A payload refused: counted by its reason, logged once per key. `as_json`: it
        is not even JSON (what the tap itself refuses), else not the message its key
        carries (what a sink refuses)."""
        reason = error.reason
        invalid = as_json and reason is bus_codec.DropReason.INVALID
        self.drop("not JSON" if invalid else str(reason))
        # A flood on ever new keys is counted, not remembered.
        if key not in self._bad_keys and len(self._bad_keys) < MAX_BAD_KEYS_LOGGED:
            self._bad_keys.add(key)
            log.warning("%s: %s; further ones counted", self._refused, error)

    # ---- the bus's threads: only queue ---------------------------------------------------
    def _enqueue(self, heard: Heard | BusSample) -> None:
        if len(self._queue) >= self._queue_limit:
            self.drop(f"{self._name} behind")
            return
        self._queue.append(heard)

    def on_sample(self, sample: BusSample) -> None:
        """A sample heard (queued as it is: the worker reads it, and drops a delete)."""
        self._enqueue(sample)

    def _on_alive(self, key: str, alive: bool) -> None:
        self._enqueue(Heard(key, alive_payload(alive), time.time_ns()))

    def _poll_states(self) -> None:
        period = 0.0  # the first at once, so a view shows the phases from the start
        answered = [0]  # in the last round: the replies come on the bus's threads

        def on_state(sample: BusSample) -> None:
            answered[0] += 1
            self.on_sample(sample)

        while not self._stop.wait(period):
            period = state_period(self._state_every_s, answered[0])
            answered[0] = 0
            try:
                self._bus.get(self.space.all_state, on_state, timeout=self._state_every_s)
            except Exception as error:  # the session closing under it: try again later
                log.warning("state query failed: %s", error)

    # ---- the worker thread ---------------------------------------------------------------
    def _work(self) -> None:
        try:
            while not self._stop.wait(self._batch_s):
                self._take_queued()
                self._sink.tick()
            # Whatever arrived before the subscriptions went is taken too.
            self._take_queued()
        except OSError as error:
            self.failure = error
            if self._on_failure is not None:
                self._on_failure(error)
            else:
                log.error("%s stopped: %s", self._name, error)

    def _take_queued(self) -> None:
        queued = self._queue
        for _ in range(len(queued)):  # bounded: what is there now; the rest next time
            item = queued.popleft()
            if isinstance(item, Heard):
                self._take(item)
            else:
                self._take_sample(item)
        ring = self._ring
        if ring is not None and self._ring_limit is not None:
            for _ in range(self._ring_limit):
                sample = ring.try_recv()
                if sample is None:
                    break
                self._take_sample(sample)

    def _take_sample(self, sample: BusSample) -> None:
        if sample.deleted:
            self.drop("delete")
            return
        when = sample.time_ns if sample.time_ns is not None else time.time_ns()
        self._take(Heard(sample.key, sample.payload, when))

    def _channel(self, key: str) -> ChannelSpec | None:
        """The channel of `key`; None (counted) for a key beyond the limits."""
        spec = self._specs.get(key)
        if spec is not None:
            return spec
        spec = channels.heard_channel(self.space.prefix, key)
        if self.max_channels is not None and self._channels >= self.max_channels:
            self.drop("too many keys")
            return None
        unknown = not spec.schema_name and key not in self._unknown_keys
        if unknown and self.max_unknown_keys is not None:
            # A key of no known pattern is a channel of its own; a peer writing on ever
            # new keys (any UAV may, under its own tree) must not grow the channel table
            # and counters without bound.
            if len(self._unknown_keys) >= self.max_unknown_keys:
                self.drop("too many unknown keys")
                return None
            self._unknown_keys.add(key)
        self._channels += 1
        if len(self._specs) < MAX_CACHED:
            self._specs[key] = spec
        return spec

    def _take(self, heard: Heard) -> None:
        spec = self._channel(heard.key)
        if spec is None or not self._sink.keep(heard, spec):
            return
        try:
            # Any JSON, but not too large or deep to decode safely (bus_codec's limits).
            value = bus_codec.decode_json(heard.payload, Any, heard.key)
        except bus_codec.BadMessage as error:
            self.refuse(heard.key, error)
            return
        try:
            self._sink.write(heard, spec, value)
        except OSError:
            raise
        except Exception:  # a bug in a sink must not end the tap: log it, go on
            log.exception("cannot take %s", heard.key)
            self.drop("error")
