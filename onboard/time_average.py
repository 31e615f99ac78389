"""An exponential moving average in time, and the aircraft's clock to run it on.

The module averages what the autopilot reports (its wind estimate, its airspeed) over a
time constant, not over a number of samples: telemetry comes at an irregular rate. The
time is the aircraft's (`AircraftClock`): a simulator at `--speedup 4` flies 80 s of
weather in 20 s of wall time, and an average that ran on the wall clock would then span
four times the weather it was tuned for (a drift seen four times later). Pure: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["AircraftClock", "TimeAverage"]


@dataclass
class TimeAverage:
    """Samples (tuples of floats of one length) averaged over `time_constant_s`: a
    sample `dt` seconds after the last moves the average by `1 - exp(-dt / tau)` of the
    way to it. The first sample, one from a time gone back, or one of another length is
    taken as it is (a restart, not weighed by a negative time); a time constant of zero
    or less follows each sample as it is."""

    time_constant_s: float
    value: tuple[float, ...] | None = None
    at: float | None = None

    def add(self, sample: tuple[float, ...], at: float) -> tuple[float, ...]:
        held, last = self.value, self.at
        if (
            held is None
            or last is None
            or at < last
            or len(sample) != len(held)
            or self.time_constant_s <= 0.0
        ):
            self.value, self.at = sample, at
            return sample
        weight = 1.0 - math.exp(-(at - last) / self.time_constant_s)
        self.value = tuple(h + weight * (s - h) for h, s in zip(held, sample, strict=True))
        self.at = at
        return self.value

    def reset(self) -> None:
        self.value = self.at = None


@dataclass
class AircraftClock:
    """Seconds of the aircraft's time since the first telemetry, never going back.

    Each telemetry advances it by the autopilot's own clock (`system_time_ms`) since the
    last one; where that clock did not move forward (a source without one, a restarted
    or wrapped autopilot clock), by the wall time between the two telemetries instead,
    so the averages still move."""

    now_s: float = 0.0
    _system_ms: int | None = None
    _wall: float | None = None

    def tick(self, system_time_ms: int, wall: float) -> float:
        last_ms, last_wall = self._system_ms, self._wall
        self._system_ms, self._wall = system_time_ms, wall
        if last_ms is None or last_wall is None:
            return self.now_s
        if system_time_ms > last_ms:
            self.now_s += (system_time_ms - last_ms) / 1000.0
        elif wall > last_wall:
            self.now_s += wall - last_wall
        return self.now_s
