"""Each aircraft's streams in a recording: samples counted per UAV and channel, and a
telemetry stream that stopped while the fleet's others flowed.

Why: an aircraft's telemetry can stop reaching the recorder while everything else of it
(its state, link, status) still does, and nothing said so until someone read the
recording (a Zenoh publisher that lost its subscribers: docs/recording.md). The
recorder counts as it writes (`StreamCounts`, on its writer thread; read from another),
`fleet up` warns while it runs (`StreamCounts.stalled`), and `fleet report` says so of
a finished recording (`stopped_telemetry`).
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from fleet.mission.key_space import uav_id_of

#: A UAV's telemetry silent this long, while other streams flow, has stopped, seconds
#: (telemetry is recorded five times a second).
STALL_S = 5.0
TELEMETRY = "telemetry"
ALIVE = "alive"


@dataclass(frozen=True)
class Stall:
    """A UAV whose telemetry stopped while other streams flowed."""

    uav: int
    #: Seconds since its last telemetry (since it was first heard, if it never had any).
    silent_s: float
    #: Its telemetry samples recorded so far.
    samples: int

    def __str__(self) -> str:
        return (
            f"UAV {self.uav}'s telemetry stopped reaching the recorder {self.silent_s:.0f} s ago "
            f"({self.samples} samples recorded) while the fleet's other streams flow"
        )


@dataclass
class StreamCounts:
    """Samples recorded per (UAV, channel leaf), and when each was last heard."""

    prefix: str
    clock: Callable[[], float] = time.monotonic
    counts: Counter[tuple[int, str]] = field(default_factory=Counter)
    _last: dict[tuple[int, str], float] = field(default_factory=dict)
    _first: dict[int, float] = field(default_factory=dict)
    _gone: set[int] = field(default_factory=set)
    #: The counts when the window `telemetry` compares opened and closed (`open_window`,
    #: `close_window`); None: from the first sample, to the last.
    _opened: Counter[tuple[int, str]] | None = None
    _closed: Counter[tuple[int, str]] | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def heard(self, key: str, value: object) -> None:
        """A sample on `key` (its payload decoded as `value`) was recorded."""
        head = f"{self.prefix}/uav/"
        if not key.startswith(head):
            return
        try:
            uav = uav_id_of(key)
        except (ValueError, IndexError):
            return
        leaf = key[len(head) :].partition("/")[2]
        now = self.clock()
        with self._lock:
            self.counts[uav, leaf] += 1
            self._last[uav, leaf] = now
            self._first.setdefault(uav, now)
            if leaf == ALIVE and isinstance(value, dict):
                if value.get(ALIVE) is False:
                    self._gone.add(uav)
                else:
                    self._gone.discard(uav)

    def open_window(self) -> None:
        """From now on `telemetry` counts: every UAV flies (`fleet up` is ready). The
        onboards start one after another, so before this a UAV started late has fewer
        samples than its teammates without any being lost."""
        with self._lock:
            self._opened = Counter(self.counts)

    def close_window(self) -> None:
        """`telemetry` counts no further: the fleet is being stopped, and its onboards
        end one after another."""
        with self._lock:
            self._closed = Counter(self.counts)

    def telemetry(self) -> dict[int, int]:
        """Telemetry samples recorded per UAV (0 for a UAV heard only otherwise), in the
        window if one was opened (and up to its close, if closed)."""
        with self._lock:
            end = self.counts if self._closed is None else self._closed
            start = Counter[tuple[int, str]]() if self._opened is None else self._opened
            return {uav: end[uav, TELEMETRY] - start[uav, TELEMETRY] for uav in sorted(self._first)}

    def stalled(self, stall_s: float = STALL_S) -> list[Stall]:
        """The UAVs still alive whose telemetry has been silent `stall_s` while another
        UAV's telemetry, or one of its own other channels, was heard within it."""
        now = self.clock()
        with self._lock:
            recent = {key for key, when in self._last.items() if now - when < stall_s}
            stalls = []
            for uav, first in self._first.items():
                if uav in self._gone or (uav, TELEMETRY) in recent:
                    continue
                silent = now - self._last.get((uav, TELEMETRY), first)
                if silent < stall_s:
                    continue
                others = any(
                    (u != uav and leaf == TELEMETRY) or (u == uav and leaf != ALIVE)
                    for u, leaf in recent
                )
                if others:
                    stalls.append(Stall(uav, silent, self.counts[uav, TELEMETRY]))
            return sorted(stalls, key=lambda stall: stall.uav)


def stopped_telemetry(
    last_s: Mapping[int, float | None], samples: Mapping[int, int], stall_s: float = STALL_S
) -> list[str]:
    """Of a finished recording: each UAV whose telemetry ended (or never began) more than
    `stall_s` before another UAV's did. `last_s`: each UAV's last telemetry (s into the
    recording; None: none), `samples`: how many it has."""
    ends = [t for t in last_s.values() if t is not None]
    if not ends:
        return []
    latest = max(ends)
    lines = []
    for uav in sorted(last_s):
        last = last_s[uav]
        if last is None:
            lines.append(f"UAV {uav} has no telemetry in the recording; others do")
        elif latest - last > stall_s:
            lines.append(
                f"UAV {uav}'s telemetry stopped at {last:.1f} s ({samples.get(uav, 0)} samples) "
                f"while others' went on to {latest:.1f} s"
            )
    return lines


def short_streams(samples: Mapping[int, int], ratio: float = 0.5) -> list[str]:
    """Each UAV with fewer than `ratio` times the median UAV's telemetry samples."""
    if len(samples) < 2:
        return []
    ordered = sorted(samples.values())
    median = ordered[len(ordered) // 2]
    return [
        f"UAV {uav}'s telemetry: {count} samples recorded, the median UAV's {median}"
        for uav, count in sorted(samples.items())
        if count < ratio * median
    ]
