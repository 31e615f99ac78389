"""A bus callback that keeps what it was given, for tests to read while the bus's
threads call in."""

from __future__ import annotations

import threading

from fleet.transport.bus import BusSample


class Heard:
    """The samples a subscription (or a ring drained into it) delivered, in order;
    `arrived` is set at the first."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._samples: list[BusSample] = []
        self.arrived = threading.Event()

    def __call__(self, sample: BusSample) -> None:
        with self._lock:
            self._samples.append(sample)
        self.arrived.set()

    @property
    def samples(self) -> list[BusSample]:
        with self._lock:
            return list(self._samples)

    @property
    def payloads(self) -> list[bytes]:
        return [sample.payload for sample in self.samples]

    def __contains__(self, payload: bytes) -> bool:
        return payload in self.payloads
