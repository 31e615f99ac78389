"""A `Bus` that loses or holds back some of its puts: fault injection for tests.

Wraps any bus (a `ZenohBus`, a `MemoryBus`): a test builds a process on it to see what
the rest of the fleet makes of a lost or late publication, without the process itself
having a switch for it. Rules match the put's key by Zenoh key expression; the first
rule that matches decides. Everything but `put` (and `publish`, which puts) is the
wrapped bus's own.
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from dataclasses import dataclass

import zenoh

from fleet.transport.bus import (
    Bus,
    DelegatingBus,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FaultRule:
    """What happens to the puts on keys within `key_expr`."""

    key_expr: str
    #: The first this many puts on each matching key are dropped (counted per key).
    drop_first: int = 0
    #: Every put not dropped goes on the bus this many seconds late (from a timer thread).
    delay_s: float = 0.0

    def matches(self, key: str) -> bool:
        return bool(zenoh.KeyExpr(self.key_expr).intersects(zenoh.KeyExpr(key)))


class FaultyBus(DelegatingBus):
    """`inner` with `rules` applied to its puts; `dropped` and `delayed` count, per key,
    what they did. Owns `inner`: closing this closes it."""

    def __init__(self, inner: Bus, *rules: FaultRule) -> None:
        self.inner = inner
        self.rules = rules
        self.dropped: Counter[str] = Counter()
        self.delayed: Counter[str] = Counter()
        self._lock = threading.Lock()  # puts come from several threads (link, main loop)
        self._timers: set[threading.Timer] = set()
        self._closed = False

    def put(self, key: str, payload: bytes) -> None:
        rule = next((r for r in self.rules if r.matches(key)), None)
        if rule is None:
            self.inner.put(key, payload)
            return
        with self._lock:
            if self._closed:
                return
            drop = self.dropped[key] < rule.drop_first
            if drop:
                self.dropped[key] += 1
            elif rule.delay_s > 0:
                self.delayed[key] += 1
                timer = threading.Timer(rule.delay_s, self._put_late, (key, payload))
                timer.daemon = True
                self._timers.add(timer)
                timer.start()
                return
        if drop:
            log.warning("fault injected: put on %s dropped", key)
        else:
            self.inner.put(key, payload)

    def _put_late(self, key: str, payload: bytes) -> None:
        with self._lock:
            if self._closed:
                return
            self._timers = {t for t in self._timers if t is not threading.current_thread()}
        self.inner.put(key, payload)

    @property
    def under(self) -> Bus:
        return self.inner

    def close(self) -> None:
        """Puts still held back are lost, as they would be by a process that stopped."""
        with self._lock:
            self._closed = True
            timers, self._timers = self._timers, set()
        for timer in timers:
            timer.cancel()
        self.inner.close()
