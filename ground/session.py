"""The ground's Zenoh session, and the wire format of what it sends and reads.

The ground is a Zenoh *client* of one router (the star of docs/architecture.md): a client
needs no listen port and is relayed by the router to every UAV. Opening fails fast and
clearly when nothing answers, never hangs: a refused connection fails at once, and an
endpoint that accepts TCP but never speaks Zenoh is given up after `open_timeout_s`
(Zenoh's own handshake timeout, 10 s by default, is shortened here).

Every message is a msgspec Struct in `fleet.transport.bus_codec`'s wire format (JSON, encoding
application/json), so a stock Zenoh tool reads the same values the ground does.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

import msgspec
import zenoh

from fleet.errors import FleetError
from fleet.transport import bus_codec, bus_qos
from fleet.transport.zenoh_config import (
    CONNECT_ENV,
    ZenohConfigError,
    check_endpoint,
    endpoints,
    error_text,
    make_config,
)

log = logging.getLogger(__name__)

JSON_ENCODING = str(bus_codec.ENCODING)
#: How long opening may take against an endpoint that accepts but does not answer.
DEFAULT_OPEN_TIMEOUT_S = 3.0

T = TypeVar("T")


class GroundConnectError(FleetError, RuntimeError):
    """No Zenoh router could be reached at the endpoint (or the endpoint is malformed)."""


def open_session(
    target: str | zenoh.Config, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S
) -> zenoh.Session:
    """A session to the router at `target` (an endpoint, or a whole config).

    An endpoint gives a client session to it. Raises GroundConnectError if none answers.
    """
    try:
        config = (
            make_config("client", [check_endpoint(target)]) if isinstance(target, str) else target
        )
    except ZenohConfigError as error:
        raise GroundConnectError(str(error)) from None
    where = ", ".join(endpoints(config)) or "the configured endpoints"
    config.insert_json5("transport/unicast/open_timeout", json.dumps(round(open_timeout_s * 1000)))
    try:
        session = zenoh.open(config)
    except zenoh.ZError as error:
        raise GroundConnectError(
            f"no Zenoh router answers at {where} ({error_text(error)}). "
            f"Start one with `fleet up`, or point --connect / ${CONNECT_ENV} at it."
        ) from error
    log.debug("connected to %s as %s", where, session.zid())
    return session


@contextmanager
def ground_session(
    target: str | zenoh.Config, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S
) -> Iterator[zenoh.Session]:
    """`open_session` as a context manager: the session is always closed."""
    session = open_session(target, open_timeout_s=open_timeout_s)
    with session:
        yield session


def encode(message: msgspec.Struct) -> bytes:
    return bus_codec.encode(message)


def put_message(session: zenoh.Session, key: str, message: msgspec.Struct) -> None:
    """Publish with the key's priority: mission messages never queue behind telemetry."""
    bus_qos.put(session, key, bus_codec.encode(message))


def decode_sample(sample: zenoh.Sample, kind: type[T]) -> T | None:
    """The sample's payload as `kind`, or None (logged) if it is not one."""
    try:
        return bus_codec.decode(sample.payload.to_bytes(), kind, str(sample.key_expr))
    except bus_codec.BadMessage as error:
        log.warning("ignored %s", error)
    return None


@dataclass(frozen=True)
class Reply:
    """One successful reply to a query."""

    key: str
    payload: bytes
    encoding: str


def query(
    session: zenoh.Session,
    selector: str,
    timeout_s: float,
    *,
    every_reply: bool = False,
    payload: bytes | None = None,
) -> list[Reply]:
    """Every successful reply to `selector` within `timeout_s`; errors are logged.

    `every_reply`: ask every matching queryable and keep each one's reply, even several
    for one key (Zenoh otherwise consolidates replies on the same key into one).
    `payload`: sent with the query, for the queryables that read it.
    """
    replies: list[Reply] = []
    options: dict[str, Any] = (
        {"target": zenoh.QueryTarget.ALL, "consolidation": zenoh.ConsolidationMode.NONE}
        if every_reply
        else {}
    )
    if payload is not None:
        options["payload"] = payload
    for reply in session.get(selector, timeout=timeout_s, **options):
        sample = reply.ok
        if sample is None:
            error = reply.err
            log.debug(
                "query %s: error reply %s", selector, error.payload.to_string() if error else ""
            )
            continue
        replies.append(Reply(str(sample.key_expr), sample.payload.to_bytes(), str(sample.encoding)))
    return replies


def query_messages(
    session: zenoh.Session, selector: str, kind: type[T], timeout_s: float
) -> list[tuple[str, T]]:
    """The replies to `selector` that decode as `kind`, with their keys."""
    found: list[tuple[str, T]] = []
    for reply in query(session, selector, timeout_s):
        try:
            found.append((reply.key, bus_codec.decode(reply.payload, kind, reply.key)))
        except bus_codec.BadMessage as error:
            log.warning("ignored reply %s", error)
    return found


def live_tokens(session: zenoh.Session, selector: str, timeout_s: float) -> list[str]:
    """The keys of the liveliness tokens alive under `selector`."""
    keys: list[str] = []
    for reply in session.liveliness().get(selector, timeout=timeout_s):
        if reply.ok is not None:
            keys.append(str(reply.ok.key_expr))
    return keys


def decode_value(payload: bytes, encoding: str) -> Any:
    """A payload for display: JSON decoded, text as text, anything else as hex.

    A payload too large or nested too deep to decode safely is shown as what it is.
    """
    if len(payload) > bus_codec.MAX_PAYLOAD_BYTES:
        return {"refused": f"{len(payload)} bytes, too large to show", "bytes": len(payload)}
    if encoding.startswith(JSON_ENCODING):
        value = _json_or_none(payload)
        if value is not None:
            return value
    if encoding.startswith(("text/", "application/json", "zenoh/string")):
        try:
            return payload.decode("utf-8")
        except UnicodeDecodeError:
            pass
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError:
        return {"hex": payload.hex(), "bytes": len(payload)}
    # Undeclared encodings that happen to hold JSON are still shown decoded.
    value = _json_or_none(payload)
    return text if value is None else value


def _json_or_none(payload: bytes) -> Any:
    """The JSON value in `payload`; None if it is not JSON; a note if it is too deep."""
    try:
        return msgspec.json.decode(payload)
    except msgspec.DecodeError:
        return None
    except RecursionError:
        bus_codec.DROPPED.add(bus_codec.DropReason.TOO_DEEP)
        return {"refused": "JSON nested too deep to show", "bytes": len(payload)}
