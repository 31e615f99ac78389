"""In-memory backends of `Link` and `Bus`, for tests in one process without sockets.

Like python-can's `interfaces/virtual.py`: every `MemoryBus` made on one `MemoryNetwork`
sees the others' publications, queryables and liveliness tokens, with Zenoh's key
expression matching; `memory_link_pair` gives the two ends of a byte pipe (an
onboard's port and a simulated autopilot's). Delivery is synchronous, on the caller's
thread, never under a lock, so a callback may publish in turn. End-to-end tests keep
using real processes, real Zenoh and real serial links: these are for unit tests.
"""

from __future__ import annotations

import itertools
import threading
import time
from dataclasses import dataclass, field

import zenoh

from fleet.transport.bus import (
    Bus,
    BusQuery,
    BusReply,
    BusSample,
    Declaration,
    PresenceCallback,
    Queryable,
    QueryNotify,
    SampleCallback,
)
from fleet.transport.link import Link


# ---- links --------------------------------------------------------------------------------------
@dataclass
class _Pipe:
    lock: threading.Lock = field(default_factory=threading.Lock)
    buffers: tuple[bytearray, bytearray] = field(default_factory=lambda: (bytearray(), bytearray()))
    connected: bool = True


class MemoryLink(Link):
    """One end of an in-memory byte pipe; `_Pipe.connected` False is a dropped link."""

    def __init__(self, name: str, pipe: _Pipe, side: int) -> None:
        self.name = name
        self._pipe = pipe
        self._side = side

    @property
    def up(self) -> bool:
        return self._pipe.connected

    def ensure_open(self, now: float) -> bool:
        return self._pipe.connected

    def read(self, now: float) -> bytes:
        with self._pipe.lock:
            inbox = self._pipe.buffers[self._side]
            data = bytes(inbox)
            inbox.clear()
        return data if self._pipe.connected else b""

    def write(self, data: bytes, now: float) -> bool:
        if not self._pipe.connected:
            return False
        with self._pipe.lock:
            self._pipe.buffers[1 - self._side].extend(data)
        return True

    def close(self) -> None:
        """Closing an end leaves the pipe as it is: the other end may still be read."""

    def disconnect(self) -> None:
        """Drop the link (both ends see it down) until `reconnect`; bytes in flight are lost."""
        with self._pipe.lock:
            self._pipe.connected = False
            for buffer in self._pipe.buffers:
                buffer.clear()

    def reconnect(self) -> None:
        self._pipe.connected = True


def memory_link_pair(name: str) -> tuple[MemoryLink, MemoryLink]:
    """The two ends of one pipe: what one writes, the other reads."""
    pipe = _Pipe()
    return MemoryLink(name, pipe, 0), MemoryLink(name, pipe, 1)


# ---- the bus ------------------------------------------------------------------------------------
def _intersects(a: str, b: str) -> bool:
    return bool(zenoh.KeyExpr(a).intersects(zenoh.KeyExpr(b)))


def _checked(key_expr: str) -> str:
    """`key_expr`, or zenoh.ZError if it is none: refused where a Zenoh session refuses
    it (when declared or asked), not at the first put it would have matched."""
    zenoh.KeyExpr(key_expr)
    return key_expr


@dataclass
class _Subscription:
    key_expr: str
    callback: SampleCallback
    owner: MemoryBus


@dataclass
class _Presence:
    key_expr: str
    callback: PresenceCallback
    owner: MemoryBus


class MemoryNetwork:
    """What every MemoryBus made on it shares: subscriptions, queryables, tokens."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.subscriptions: list[_Subscription] = []
        self.presence: list[_Presence] = []
        self.queryables: list[MemoryQueryable] = []
        #: Token id -> (key, owner).
        self.tokens: dict[int, tuple[str, MemoryBus]] = {}
        self._ids = itertools.count()

    def bus(self) -> MemoryBus:
        return MemoryBus(self)

    def next_id(self) -> int:
        return next(self._ids)

    def token_change(self, key: str, alive: bool) -> None:
        with self.lock:
            watchers = [p.callback for p in self.presence if _intersects(p.key_expr, key)]
        for callback in watchers:
            callback(key, alive)


class _Undeclare:
    def __init__(self, action: object) -> None:
        self._action = action
        self._done = False

    def undeclare(self) -> None:
        if not self._done:
            self._done = True
            assert callable(self._action)
            self._action()


class MemoryQuery(BusQuery):
    def __init__(
        self, key: str, payload: bytes, callback: SampleCallback, parameters: str = ""
    ) -> None:
        self.key = key
        self.payload = payload
        self.parameters = parameters
        self._callback = callback
        #: Set by `drop`: the answerer is done with the query.
        self.done = threading.Event()
        #: Error replies, for tests to read.
        self.errors: list[str] = []

    def intersects(self, key: str) -> bool:
        return _intersects(self.key, key)

    def reply_bytes(self, key: str, payload: bytes) -> None:
        if not self.done.is_set():
            self._callback(BusSample(key, payload))

    def reply_err(self, text: str) -> None:
        self.errors.append(text)

    def drop(self) -> None:
        self.done.set()


class MemoryQueryable(Queryable):
    def __init__(
        self,
        network: MemoryNetwork,
        key_expr: str,
        owner: MemoryBus,
        notify: QueryNotify | None = None,
    ) -> None:
        super().__init__(notify)
        self.key_expr = key_expr
        self.owner = owner
        self._network = network

    def undeclare(self) -> None:
        with self._network.lock:
            if self in self._network.queryables:
                self._network.queryables.remove(self)


class MemoryBus(Bus):
    """One participant of a MemoryNetwork (an onboard, a ground, a test)."""

    def __init__(self, network: MemoryNetwork) -> None:
        self.network = network
        self.closed = False

    def put(self, key: str, payload: bytes) -> None:
        with self.network.lock:
            callbacks = [
                s.callback for s in self.network.subscriptions if _intersects(s.key_expr, key)
            ]
        sample = BusSample(key, payload)
        for callback in callbacks:
            callback(sample)

    def subscribe(
        self, key_expr: str, callback: SampleCallback, *, details: bool = False
    ) -> Declaration:
        # In memory every sample carries its details anyway.
        entry = _Subscription(_checked(key_expr), callback, self)
        with self.network.lock:
            self.network.subscriptions.append(entry)
        return _Undeclare(lambda: self._remove(self.network.subscriptions, entry))

    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        """Queue the query at every intersecting queryable; replies reach `callback` when
        their owners answer. The timeout is not enforced: a test bounds its own waits."""
        self._ask(selector, payload, callback)

    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        """Ask every intersecting queryable and wait until each has dropped its query, or
        `timeout` has passed. Without `every_reply`, one reply per key (the last), as
        Zenoh's consolidation keeps one."""
        lock = threading.Lock()
        replies: list[BusReply] = []

        def on_reply(sample: BusSample) -> None:
            with lock:
                replies.append(BusReply(sample.key, sample.payload))

        queries = self._ask(selector, payload, on_reply)
        deadline = time.monotonic() + timeout
        for query in queries:
            query.done.wait(max(0.0, deadline - time.monotonic()))
        with lock:
            found = list(replies)
        if not every_reply:
            found = list({reply.key: reply for reply in found}.values())
        errors = [BusReply("", text.encode(), ok=False) for q in queries for text in q.errors]
        return found + errors

    def _ask(self, selector: str, payload: bytes, callback: SampleCallback) -> list[MemoryQuery]:
        expr, _, parameters = selector.partition("?")
        key = _checked(expr)
        with self.network.lock:
            targets = [q for q in self.network.queryables if _intersects(q.key_expr, key)]
        queries = [MemoryQuery(key, payload, callback, parameters) for _ in targets]
        for queryable, query in zip(targets, queries, strict=True):
            queryable.deliver(query)
        return queries

    def declare_queryable(self, key_expr: str, notify: QueryNotify | None = None) -> Queryable:
        queryable = MemoryQueryable(self.network, _checked(key_expr), self, notify)
        with self.network.lock:
            self.network.queryables.append(queryable)
        return queryable

    def declare_token(self, key: str) -> Declaration:
        token = self.network.next_id()
        with self.network.lock:
            self.network.tokens[token] = (key, self)
        self.network.token_change(key, True)
        return _Undeclare(lambda: self._drop_token(token))

    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        _checked(key_expr)
        with self.network.lock:
            return [k for k, _ in self.network.tokens.values() if _intersects(key_expr, k)]

    def subscribe_presence(self, key_expr: str, callback: PresenceCallback) -> Declaration:
        entry = _Presence(_checked(key_expr), callback, self)
        with self.network.lock:
            self.network.presence.append(entry)
            present = [k for k, _ in self.network.tokens.values() if _intersects(key_expr, k)]
        for key in present:  # history: the tokens already there
            callback(key, True)
        return _Undeclare(lambda: self._remove(self.network.presence, entry))

    def close(self) -> None:
        """Leave: our declarations go, and our tokens vanish for everyone else."""
        if self.closed:
            return
        self.closed = True
        network = self.network
        with network.lock:
            network.subscriptions = [s for s in network.subscriptions if s.owner is not self]
            network.presence = [p for p in network.presence if p.owner is not self]
            network.queryables = [q for q in network.queryables if q.owner is not self]
            ours = [token for token, (_, owner) in network.tokens.items() if owner is self]
        for token in ours:
            self._drop_token(token)

    def _drop_token(self, token: int) -> None:
        with self.network.lock:
            entry = self.network.tokens.pop(token, None)
        if entry is not None:
            self.network.token_change(entry[0], False)

    def _remove(self, entries: list[_Subscription] | list[_Presence], entry: object) -> None:
        with self.network.lock:
            if entry in entries:
                entries.remove(entry)  # type: ignore[arg-type]
