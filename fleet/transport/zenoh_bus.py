"""The Zenoh backend of `fleet.transport.bus.Bus`: one Zenoh session.

Every callback runs directly on the Zenoh thread that received the data
(`zenoh.handlers.Callback(..., indirect=False)`). zenoh-python's default runs each
subscription's, queryable's and query's callback in a Python thread of its own: 11
long-lived threads per onboard process, one more per query in flight, and a thread
hand-off per sample. The bus's callbacks only decode and queue (`fleet.transport.bus`:
they never wait), so they need no thread of their own. (`indirect` is marked unstable
in zenoh-python; the dependency is pinned to 1.10.)

A ground tool is a Zenoh *client* of one router (the star of docs/architecture.md): a
client needs no listen port and is relayed by the router to every UAV. `connect` opens
one and fails fast and clearly when nothing answers, never hangs: a refused connection
fails at once, and an endpoint that accepts TCP but never speaks Zenoh is given up after
`open_timeout_s` (Zenoh's own handshake timeout, 10 s by default, is shortened).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import zenoh

from fleet.errors import FleetError
from fleet.transport import bus_codec, bus_qos
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
from fleet.transport.zenoh_config import (
    CONNECT_ENV,
    ZenohConfigError,
    check_endpoint,
    endpoints,
    error_text,
    make_config,
)

log = logging.getLogger(__name__)

_T = TypeVar("_T")

#: Where a client connects: a router's endpoint, or a whole Zenoh config.
ClientTarget = str | zenoh.Config
#: How long opening may take against an endpoint that accepts but does not answer.
DEFAULT_OPEN_TIMEOUT_S = 3.0


class BusConnectError(FleetError, RuntimeError):
    """No Zenoh router could be reached at the endpoint (or the endpoint is malformed)."""


def direct(callback: Callable[[_T], Any]) -> zenoh.handlers.Callback[_T]:
    """`callback` run on the Zenoh thread that received the data, not a thread of its own."""
    return zenoh.handlers.Callback(callback, indirect=False)


def _plain(sample: zenoh.Sample) -> BusSample:
    """Key and payload only: what every subscription of the fleet reads."""
    return BusSample(str(sample.key_expr), sample.payload.to_bytes())


def _sample(sample: zenoh.Sample) -> BusSample:
    return BusSample(
        str(sample.key_expr),
        sample.payload.to_bytes(),
        str(sample.encoding),
        sample.kind == zenoh.SampleKind.DELETE,
    )


def _reply(reply: zenoh.Reply) -> BusReply:
    sample = reply.ok
    if sample is not None:
        return BusReply(str(sample.key_expr), sample.payload.to_bytes(), True, str(sample.encoding))
    error = reply.err
    if error is None:  # neither: not produced by zenoh 1.x, kept for the type checker
        return BusReply("", b"", False, "")
    return BusReply("", error.payload.to_bytes(), False, str(error.encoding))


class ZenohQuery(BusQuery):
    def __init__(self, query: zenoh.Query) -> None:
        self._query = query
        self.key = str(query.key_expr)
        self.payload = query.payload.to_bytes() if query.payload is not None else b""

    def intersects(self, key: str) -> bool:
        return bool(self._query.key_expr.intersects(zenoh.KeyExpr(key)))

    def reply_bytes(self, key: str, payload: bytes) -> None:
        self._query.reply(key, payload, encoding=bus_codec.ENCODING)

    def reply_err(self, text: str) -> None:
        self._query.reply_err(text.encode())

    def drop(self) -> None:
        self._query.drop()


class ZenohQueryable(Queryable):
    """Queries queued by a Zenoh callback, which then calls `notify`."""

    def __init__(self, session: zenoh.Session, key_expr: str, notify: QueryNotify | None) -> None:
        super().__init__(notify)
        self._queryable = session.declare_queryable(key_expr, direct(self._on_query))

    def _on_query(self, query: zenoh.Query) -> None:
        self.deliver(ZenohQuery(query))

    def undeclare(self) -> None:
        self._queryable.undeclare()


class ZenohBus(Bus):
    """A Bus over a Zenoh session, which it owns (closed by `close`)."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        #: Declared publishers of the keys put at a steady rate (telemetry), by key.
        self._publishers: dict[str, zenoh.Publisher] = {}

    @classmethod
    def open(cls, config: zenoh.Config) -> ZenohBus:
        """Open a session; raises zenoh.ZError if the config's router cannot be reached."""
        return cls(zenoh.open(config))

    def put(self, key: str, payload: bytes) -> None:
        """Publish with the key's priority and congestion control (bus_qos).

        Telemetry goes through a publisher declared on its first put: a put on a declared
        publisher costs about half the CPU of a session put (the key is resolved once, not
        at each of the 20 puts a second), which counts in an idle onboard (issue 14).
        """
        publisher = self._publishers.get(key)
        if publisher is None:
            qos = bus_qos.qos_for(key)
            if qos is not bus_qos.TELEMETRY:
                bus_qos.put(self.session, key, payload, qos)
                return
            publisher = self._publishers.setdefault(key, bus_qos.declare(self.session, key, qos))
        publisher.put(payload)

    def subscribe(
        self, key_expr: str, callback: SampleCallback, *, details: bool = False
    ) -> Declaration:
        convert = _sample if details else _plain

        def on_sample(sample: zenoh.Sample) -> None:
            callback(convert(sample))

        subscriber: Declaration = self.session.declare_subscriber(key_expr, direct(on_sample))
        return subscriber

    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                callback(_sample(reply.ok))

        if payload:
            self.session.get(selector, direct(on_reply), payload=payload, timeout=timeout)
        else:
            self.session.get(selector, direct(on_reply), timeout=timeout)

    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        options: dict[str, Any] = (
            {"target": zenoh.QueryTarget.ALL, "consolidation": zenoh.ConsolidationMode.NONE}
            if every_reply
            else {}
        )
        if payload:
            options["payload"] = payload
        return [_reply(reply) for reply in self.session.get(selector, timeout=timeout, **options)]

    def declare_queryable(self, key_expr: str, notify: QueryNotify | None = None) -> Queryable:
        return ZenohQueryable(self.session, key_expr, notify)

    def declare_token(self, key: str) -> Declaration:
        token: Declaration = self.session.liveliness().declare_token(key)
        return token

    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        replies = self.session.liveliness().get(key_expr, timeout=timeout)
        return [str(reply.ok.key_expr) for reply in replies if reply.ok is not None]

    def subscribe_presence(self, key_expr: str, callback: PresenceCallback) -> Declaration:
        def on_token(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        subscriber: Declaration = self.session.liveliness().declare_subscriber(
            key_expr, direct(on_token), history=True
        )
        return subscriber

    def close(self) -> None:
        self._publishers.clear()  # closing the session undeclares them
        self.session.close()


def connect(target: ClientTarget, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S) -> ZenohBus:
    """A bus to the router at `target` (an endpoint, or a whole config).

    An endpoint gives a client session to it. Raises BusConnectError if none answers.
    """
    try:
        config = (
            make_config("client", [check_endpoint(target)]) if isinstance(target, str) else target
        )
    except ZenohConfigError as error:
        raise BusConnectError(str(error)) from None
    where = ", ".join(endpoints(config)) or "the configured endpoints"
    config.insert_json5("transport/unicast/open_timeout", json.dumps(round(open_timeout_s * 1000)))
    try:
        session = zenoh.open(config)
    except zenoh.ZError as error:
        raise BusConnectError(
            f"no Zenoh router answers at {where} ({error_text(error)}). "
            f"Start one with `fleet up`, or point --connect / ${CONNECT_ENV} at it."
        ) from error
    log.debug("connected to %s as %s", where, session.zid())
    return ZenohBus(session)


@contextmanager
def client_bus(
    target: ClientTarget, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S
) -> Iterator[ZenohBus]:
    """`connect` as a context manager: the bus is always closed."""
    bus = connect(target, open_timeout_s=open_timeout_s)
    try:
        yield bus
    finally:
        bus.close()
