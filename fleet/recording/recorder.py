"""Record the fleet's key space from its bus into MCAP (`fleet record`).

What is recorded is what the bus tap hears (fleet.recording.bus_tap):

* every sample put under the expression (default `{prefix}/**`), on a channel per key;
* each UAV's state (`{prefix}/uav/*/state`, a queryable that is never published), by a
  query every `state_every_s` (in a fleet of more than 10, every N / 10 s), so the
  mission phases are in the recording;
* each UAV's liveliness token appearing or going (`.../alive`, `{"alive": bool}`);

and, made up here, a `foxglove.LocationFix` from each UAV's telemetry, for Foxglove's
map, one every `fix_every_s` per UAV (1 s by default; 0: one per telemetry).

Telemetry is recorded at most every `telemetry_every_s` per key (5 Hz; 0: every one;
`fleet.recording.thinning`): the live rate is 20 Hz.

Log time is the Zenoh timestamp the router stamped on the sample where there is one,
else the time it was received. The bus's threads only queue (in the router's own
process, `in_router`, the samples wait in Zenoh's ring instead: no Python on its routing
threads); the tap's one worker owns the file and takes everything queued every
`BATCH_S`, so a slow disk never blocks Zenoh. A payload that is not JSON, or too large
or nested too deep to decode safely, is dropped, counted and logged (once per key).
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import msgspec

from fleet.mission.key_registry import TELEMETRY
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace, uav_id_of
from fleet.recording import channels
from fleet.recording.bus_tap import BATCH_S, DEFAULT_STATE_EVERY_S, BusTap, Heard
from fleet.recording.channels import ChannelSpec
from fleet.recording.streams import StreamCounts
from fleet.recording.thinning import DEFAULT_TELEMETRY_EVERY_S, TelemetryThinning
from fleet.recording.writer import McapSink
from fleet.transport.bus import Bus

__all__ = [
    "DEFAULT_FIX_EVERY_S",
    "DEFAULT_STATE_EVERY_S",
    "READY_LINE",
    "Recorder",
    "RecorderStats",
]

log = logging.getLogger(__name__)
#: How many keys of no known pattern get a channel; samples on further ones are counted.
MAX_UNKNOWN_KEYS = 1000
#: The line `fleet record` prints once it listens (the launcher waits for it).
READY_LINE = "fleet record: recording"
#: Samples waiting for the writer beyond this are dropped (and counted), not queued.
QUEUE_LIMIT = 100_000
#: Zenoh's own queue in the router's process (`in_router`): a ring whose every slot is
#: touched as it turns (100,000 held 25 MB), 10-20 s of a 50-100-UAV fleet's samples.
RING_LIMIT = 20_000
#: UAVs whose last map fix is remembered: past these, a peer making up UAV ids has their
#: telemetry recorded, not mapped.
MAX_MAPPED_UAVS = 10_000
#: One map fix per UAV this often, seconds: a track point every ~20 m at cruise speed.
DEFAULT_FIX_EVERY_S = 1.0


@dataclass
class RecorderStats:
    recorded: Counter[str] = field(default_factory=Counter)  #: per pattern
    dropped: Counter[str] = field(default_factory=Counter)  #: per reason


class Recorder:
    """Records what a tap on `bus` hears into `sink`.

    `start()` opens the file and returns once every subscription is declared; `stop()`
    undeclares them, writes what is queued and finishes the file.
    """

    def __init__(
        self,
        bus: Bus,
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
        self.sink = sink
        self.prefix = key_space.prefix
        self._fix_every_ns = round(fix_every_s * 1e9)
        self.thinning = TelemetryThinning(telemetry_every_s)
        self._last_fix_ns: dict[int, int] = {}
        self._fix_specs: dict[int, ChannelSpec] = {}  # by UAV
        #: Samples recorded per UAV and channel; whose telemetry stopped (`fleet up` asks).
        self.streams = StreamCounts(self.prefix)
        #: Why writing stopped (the disk is full, ...); `on_failure` is set then.
        self.failure: str | None = None
        self._on_failure = on_failure
        self.tap = BusTap(
            bus,
            self,
            key_space,
            expr=expr,
            state_every_s=state_every_s,
            queue_limit=QUEUE_LIMIT,
            batch_s=min(BATCH_S, sink.flush_every_s / 2),
            ring_limit=RING_LIMIT if in_router else None,
            max_unknown_keys=MAX_UNKNOWN_KEYS,
            name="writer",
            refused="not recorded",
            on_failure=self._failed,
        )
        self.expr = self.tap.expr
        self.stats = RecorderStats(dropped=self.tap.dropped)

    # ---- life cycle ----------------------------------------------------------------------
    def start(self) -> None:
        """Open the file, then subscribe; OSError, or what the bus raises for a bad
        expression (zenoh.ZError), if not."""
        self.sink.open()
        self.tap.start()

    def stop(self) -> None:
        self.tap.stop()
        with contextlib.suppress(OSError):  # already reported as the failure
            self.sink.close()

    def _failed(self, error: OSError) -> None:
        self.failure = f"cannot write {self.sink.path}: {error.strerror or error}"
        log.error("%s; recording stopped", self.failure)
        if self._on_failure is not None:
            self._on_failure.set()

    # ---- the tap's sink (its worker thread) ----------------------------------------------
    def keep(self, heard: Heard, spec: ChannelSpec) -> bool:
        return self.thinning.keep(heard.key, spec.pattern, heard.time_ns)

    def write(self, heard: Heard, spec: ChannelSpec, value: Any) -> None:
        self.sink.write(spec, heard.payload, heard.time_ns, heard.time_ns)
        self.stats.recorded[spec.pattern] += 1
        self.streams.heard(heard.key, value)
        parsed = self.tap.space.parse(heard.key)
        if parsed is not None and parsed.spec is TELEMETRY and isinstance(value, dict):
            self._write_fix(heard, value)

    def tick(self) -> None:
        self.sink.flush_if_due()

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
        if last is None and len(self._last_fix_ns) >= MAX_MAPPED_UAVS:
            return  # a peer's flood of UAV ids: their telemetry is recorded, not mapped
        self._last_fix_ns[uav] = heard.time_ns
        spec = self._fix_specs.get(uav)
        if spec is None:
            spec = self._fix_specs[uav] = channels.location_channel(self.prefix, uav)
        self.sink.write(spec, msgspec.json.encode(fix), heard.time_ns, heard.time_ns)
        self.stats.recorded[spec.pattern] += 1
