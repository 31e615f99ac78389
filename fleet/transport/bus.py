"""The message-bus interface: what a fleet process needs from Zenoh.

Shaped like python-can's `BusABC`: one abstract base with the four things the fleet
does on its bus (publish, subscribe, query and answer, liveliness), a real backend
(`fleet.transport.zenoh_bus.ZenohBus`) and an in-memory one
(`fleet.transport.memory.MemoryBus`), so an onboard process can be tested in one
process without sockets. Payloads are bytes; `publish` and `reply` put msgspec
messages in the bus codec's format (`fleet.transport.bus_codec`).

Callbacks run on the backend's threads (Zenoh's, or the caller's for the in-memory
bus): they must only hand work on, never wait.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

import msgspec

from fleet.transport import bus_codec
from fleet.transport.refusal_log import RefusalLog

log = logging.getLogger(__name__)
#: Refused input, logged at most every few seconds (a flood cannot fill the log).
_refusals = RefusalLog(log)

T = TypeVar("T")

#: The encoding of everything the fleet puts (`bus_codec.ENCODING`), as text.
JSON_ENCODING = str(bus_codec.ENCODING)


@dataclass(frozen=True)
class BusSample:
    """A value seen on the bus: a publication, or a successful reply to a query.

    `deleted`: the key was deleted (Zenoh's DELETE kind), `payload` is then empty.
    `time_ns`: when it was put, ns since the epoch, by the timestamp the router stamped
    on it (None: the bus knows none, or the subscription asked for no details). When,
    not what: two samples of the same value are equal whenever they were put.
    """

    key: str
    payload: bytes
    encoding: str = JSON_ENCODING
    deleted: bool = False
    time_ns: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class BusReply:
    """One reply to a query: a value on the replier's key, or an error (`ok` False,
    `payload` the error's text; Zenoh's error replies carry no key, so `key` is "")."""

    key: str
    payload: bytes
    ok: bool = True
    encoding: str = JSON_ENCODING
    #: Who signed it, its signature checked (the secure profile); None when unsigned.
    author: str | None = None


def decode_sample(sample: BusSample, kind: type[T]) -> T | None:
    """The payload as `kind`, or None (logged) if it is not one."""
    try:
        return bus_codec.decode(sample.payload, kind, sample.key)
    except bus_codec.BadMessage as error:
        _refusals.warn(f"ignored {error}")
    return None


#: Called with each sample a subscription or a query receives.
SampleCallback = Callable[[BusSample], None]
#: Called with (token key, alive) when a liveliness token appears or goes.
PresenceCallback = Callable[[str, bool], None]


class Declaration(Protocol):
    """Something declared on the bus (a subscription, a token); undeclared when done."""

    def undeclare(self) -> None: ...


class RingSubscription(Protocol):
    """Samples kept for the subscriber to take (`Bus.subscribe_ring`)."""

    def try_recv(self) -> BusSample | None:
        """The oldest sample kept, or None if there is none."""
        ...

    def undeclare(self) -> None: ...


class _DequeRing:
    """`subscribe_ring` on any bus: a callback appends to a bounded deque."""

    def __init__(self, bus: Bus, key_expr: str, limit: int) -> None:
        self._samples: deque[BusSample] = deque(maxlen=limit)
        self._declared = bus.subscribe(key_expr, self._samples.append, details=True)

    def try_recv(self) -> BusSample | None:
        try:
            return self._samples.popleft()
        except IndexError:
            return None

    def undeclare(self) -> None:
        self._declared.undeclare()


class BusQuery(ABC):
    """A query to one of our queryables; answer with `reply`/`reply_err`, then `drop`."""

    key: str
    payload: bytes
    #: The selector's parameters (after `?`), "" for none: `relayed` asks teammates to
    #: relay what they heard (a UAV's latest state), not only the key's owner to answer.
    parameters: str = ""

    @abstractmethod
    def intersects(self, key: str) -> bool:
        """Whether `key` falls within what the query asked for."""

    @abstractmethod
    def reply_bytes(self, key: str, payload: bytes) -> None: ...

    @abstractmethod
    def reply_err(self, text: str) -> None: ...

    @abstractmethod
    def drop(self) -> None:
        """Finish the query: the querier gets no more replies from us."""

    def reply(self, key: str, message: msgspec.Struct) -> None:
        self.reply_bytes(key, bus_codec.encode(message))


#: Called (on the backend's thread) when a query has arrived, so the owner's loop can
#: wake up and take it with `try_recv` instead of polling on a timer.
QueryNotify = Callable[[], None]


class Queryable(ABC):
    """Queries arriving on a key expression, polled by the owner's loop.

    A backend hands each arriving query to `deliver` (from any thread); the owner takes
    them with `try_recv` and is woken by `notify`, if given, when one waits."""

    def __init__(self, notify: QueryNotify | None = None) -> None:
        self._notify = notify
        self._waiting: deque[BusQuery] = deque()  # appends and pops are thread-safe

    def deliver(self, query: BusQuery) -> None:
        self._waiting.append(query)
        if self._notify is not None:
            self._notify()

    def try_recv(self) -> BusQuery | None:
        """The next waiting query, or None."""
        # Polled several times each turn of an onboard's loop, nearly always empty: a
        # length test, not a raised IndexError. Only the owner's loop pops.
        waiting = self._waiting
        return waiting.popleft() if waiting else None

    @abstractmethod
    def undeclare(self) -> None: ...


class Bus(ABC):
    """One participant's view of the fleet's key space."""

    @abstractmethod
    def put(self, key: str, payload: bytes) -> None: ...

    @abstractmethod
    def subscribe(
        self, key_expr: str, callback: SampleCallback, *, details: bool = False
    ) -> Declaration:
        """Every sample put under `key_expr`, to `callback`. Its `encoding` and `deleted`
        are read off Zenoh's sample only with `details` (`ground-cli keys` shows them);
        else they are the defaults, JSON and False: the fleet's messages are JSON, and
        reading them costs ~20 % of a sample's conversion on every subscription."""

    def subscribe_ring(self, key_expr: str, limit: int) -> RingSubscription:
        """Every sample put under `key_expr` (with its details), kept in a ring of `limit`
        (past it the oldest go, uncounted) for the subscriber to take with `try_recv`:
        no callback of the subscriber runs on the bus's threads. On Zenoh the ring is
        Zenoh's own, so not even a Python callback does (the router's own session)."""
        return _DequeRing(self, key_expr, limit)

    @abstractmethod
    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        """Query `selector` (with `payload`, e.g. a command); each successful reply goes
        to `callback` as it arrives, until `timeout` seconds have passed."""

    @abstractmethod
    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        """Every reply to `selector` (with `payload`) within `timeout` seconds, errors too.

        `every_reply`: ask every matching queryable and keep each one's reply, even several
        for one key (Zenoh otherwise asks the best-matching ones and consolidates replies
        on the same key into one).
        """

    def query_messages(self, selector: str, kind: type[T], timeout: float) -> list[tuple[str, T]]:
        """The replies to `selector` that decode as `kind`, with their keys; error replies
        are logged at debug level, undecodable ones as warnings."""
        found: list[tuple[str, T]] = []
        for reply in self.query(selector, timeout):
            if not reply.ok:
                log.debug("query %s: error reply %r", selector, reply.payload)
                continue
            try:
                found.append((reply.key, bus_codec.decode(reply.payload, kind, reply.key)))
            except bus_codec.BadMessage as error:
                _refusals.warn(f"ignored reply {error}")
        return found

    @abstractmethod
    def declare_queryable(self, key_expr: str, notify: QueryNotify | None = None) -> Queryable:
        """Queries on `key_expr`, taken with `try_recv`; `notify` is called as each arrives."""

    @abstractmethod
    def declare_token(self, key: str) -> Declaration:
        """A liveliness token: present while declared and while this bus is open."""

    @abstractmethod
    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        """The keys of the liveliness tokens present under `key_expr` now."""

    @abstractmethod
    def subscribe_presence(self, key_expr: str, callback: PresenceCallback) -> Declaration:
        """Token changes under `key_expr`, starting with the tokens present now."""

    @abstractmethod
    def close(self) -> None:
        """Leave the bus: every declaration, and every token, goes."""

    @property
    def signed(self) -> bool:
        """Whether commands and decisions on this bus are signed and checked (the secure
        profile, `fleet.transport.signing`): then a message is believed for its author."""
        return False

    def keep_latest(self, key_expr: str) -> Declaration | None:
        """In the secure profile, keep the latest signed message put on each key under
        `key_expr`, as it arrived (payload and its author's envelope, not checked here:
        whoever it is relayed to checks it), for `latest` to relay; None elsewhere (a
        relay is believed only for its author's signature)."""
        return None

    def latest(self, key: str) -> bytes | None:
        """The payload of the latest message kept on `key` (`keep_latest`), if any: a
        reply with it passes its author's envelope on."""
        return None

    def publish(self, key: str, message: msgspec.Struct) -> None:
        self.put(key, bus_codec.encode(message))


class DelegatingBus(Bus):
    """A bus that hands every call but `put` and `close` to the bus `under` it: the base
    of a wrapper that changes what it puts or when it opens."""

    @property
    @abstractmethod
    def under(self) -> Bus:
        """The bus the calls go to."""

    def subscribe(
        self, key_expr: str, callback: SampleCallback, *, details: bool = False
    ) -> Declaration:
        return self.under.subscribe(key_expr, callback, details=details)

    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        self.under.get(selector, callback, timeout, payload)

    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        return self.under.query(selector, timeout, payload, every_reply=every_reply)

    def declare_queryable(self, key_expr: str, notify: QueryNotify | None = None) -> Queryable:
        return self.under.declare_queryable(key_expr, notify)

    def declare_token(self, key: str) -> Declaration:
        return self.under.declare_token(key)

    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        return self.under.live_tokens(key_expr, timeout)

    def subscribe_presence(self, key_expr: str, callback: PresenceCallback) -> Declaration:
        return self.under.subscribe_presence(key_expr, callback)

    @property
    def signed(self) -> bool:
        return self.under.signed

    def keep_latest(self, key_expr: str) -> Declaration | None:
        return self.under.keep_latest(key_expr)

    def latest(self, key: str) -> bytes | None:
        return self.under.latest(key)
