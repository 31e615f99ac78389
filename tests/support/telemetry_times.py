"""When a raw Zenoh session heard each UAV's telemetry: to see one UAV's stream stop
while another's flows (an event to wait on, not a quiet period)."""

from __future__ import annotations

import threading
import time

import zenoh

from fleet.mission.key_space import KeySpace


class TelemetryTimes:
    """Thread-safe: Zenoh calls in. `undeclare` when done."""

    def __init__(self, session: zenoh.Session, space: KeySpace) -> None:
        self._lock = threading.Lock()
        self._heard: dict[int, list[float]] = {}
        self._space = space
        self.subscriber = session.declare_subscriber(space.all_telemetry, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        uav = int(str(sample.key_expr).removeprefix(f"{self._space.prefix}/").split("/")[1])
        with self._lock:
            self._heard.setdefault(uav, []).append(time.monotonic())

    def since(self, uav: int, moment: float) -> int:
        """Samples of `uav` heard after `moment` (time.monotonic())."""
        with self._lock:
            return sum(at > moment for at in self._heard.get(uav, ()))

    def last(self, uav: int) -> float:
        """When `uav`'s latest sample was heard (0.0: never)."""
        with self._lock:
            return max(self._heard.get(uav, ()), default=0.0)

    def stopped(self, uav: int, flowing: int, since: float, after: int) -> bool:
        """Whether `uav`'s stream has stopped: `flowing`'s has delivered `after` samples
        since both `since` and `uav`'s last one."""
        return self.since(flowing, max(since, self.last(uav))) >= after

    def undeclare(self) -> None:
        self.subscriber.undeclare()
