"""Telemetry in a recording at a sane rate: one per key every `every_s` of log time.

The autopilots send 20 Hz, which is what the onboards and the live views need; in a
recording four in five of those samples made up most of the bytes and add nothing a
plot, a report or a replay draws. A sample left out is counted, and never decoded.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: One telemetry per UAV in the file this often, seconds (the live rate is 20 Hz).
DEFAULT_TELEMETRY_EVERY_S = 0.2
#: Keys whose last kept time is remembered: past these, a peer putting telemetry on ever
#: new keys has all of it kept (as before thinning), never more memory.
MAX_KEYS = 10_000
_TELEMETRY = "/telemetry"


@dataclass
class TelemetryThinning:
    """Which telemetry samples go in the file; `every_s` 0 keeps every one."""

    every_s: float = DEFAULT_TELEMETRY_EVERY_S
    thinned: int = 0  #: samples left out
    _last_ns: dict[str, int] = field(default_factory=dict)

    def keep(self, key: str, pattern: str, time_ns: int) -> bool:
        """Whether the sample on `key` (of key pattern `pattern`) at `time_ns` is kept:
        anything but telemetry is; telemetry when none of its key was kept in the last
        `every_s` (a clock that went back starts the interval again)."""
        if self.every_s <= 0 or not pattern.endswith(_TELEMETRY):
            return True
        last = self._last_ns.get(key)
        if last is not None and 0 <= time_ns - last < self.every_s * 1e9:
            self.thinned += 1
            return False
        if last is not None or len(self._last_ns) < MAX_KEYS:
            self._last_ns[key] = time_ns
        return True
