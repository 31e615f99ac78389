"""`ground-cli keys`: the key space and each key's latest value, decoded.

Three sources, because no single one sees every key:

* a query of the expression: what is served (UAV state, mission targets, results, ...);
* a subscription held for a short window: what is only published (telemetry, track,
  status, link health), which a query never returns;
* a liveliness query: the `alive` tokens, which are neither published nor served.

With `--admin` the router's admin space (`@/**`) is queried too: `**` never matches
`@`-chunks, so it has to be asked for explicitly, exactly as a stock `z_get -s '@/**'`
does. Values are decoded for display: JSON as JSON, text as text, anything else as hex.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import msgspec

from fleet.mission.key_space import KeySpace
from fleet.transport import bus_codec
from fleet.transport.bus import JSON_ENCODING, Bus, BusReply, BusSample

log = logging.getLogger(__name__)


def default_expr(space: KeySpace) -> str:
    """Everything under the key prefix."""
    return space.everything


ADMIN_EXPR = "@/**"
#: The longest a value is shown in text mode before it is cut (--full shows all).
TEXT_WIDTH = 160


@dataclass(frozen=True)
class KeyValue:
    key: str
    encoding: str
    value: Any
    via: str  #: query | subscription | liveliness | admin

    def to_json(self) -> dict[str, Any]:
        return {"key": self.key, "encoding": self.encoding, "value": self.value, "via": self.via}


def collect(
    bus: Bus,
    expr: str,
    *,
    window_s: float,
    timeout_s: float,
    admin: bool,
) -> list[KeyValue]:
    """Every key under `expr` with its latest value, sorted by key."""
    found: dict[str, KeyValue] = {}
    lock = threading.Lock()

    def on_sample(sample: BusSample) -> None:
        if sample.deleted:
            return
        value = KeyValue(
            sample.key,
            sample.encoding,
            decode_value(sample.payload, sample.encoding),
            "subscription",
        )
        with lock:
            found[value.key] = value

    # Subscribe before querying, so a sample published meanwhile is not lost; samples
    # that arrive after the query are newer than its replies and replace them.
    subscription = bus.subscribe(expr, on_sample, details=True)
    try:
        for reply in _values(bus, expr, timeout_s):
            value = KeyValue(
                reply.key, reply.encoding, decode_value(reply.payload, reply.encoding), "query"
            )
            with lock:
                found.setdefault(value.key, value)
        for key in bus.live_tokens(expr, timeout_s):
            with lock:
                found.setdefault(key, KeyValue(key, "", "<liveliness token>", "liveliness"))
        deadline = time.monotonic() + window_s
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(min(remaining, 0.1))
    finally:
        subscription.undeclare()
    if admin and not expr.startswith("@"):
        for reply in _values(bus, ADMIN_EXPR, timeout_s):
            found.setdefault(
                reply.key,
                KeyValue(
                    reply.key, reply.encoding, decode_value(reply.payload, reply.encoding), "admin"
                ),
            )
    with lock:
        return [found[key] for key in sorted(found)]


def _values(bus: Bus, selector: str, timeout_s: float) -> list[BusReply]:
    """The successful replies to `selector`; error replies are logged."""
    replies = bus.query(selector, timeout_s)
    for reply in replies:
        if not reply.ok:
            log.debug("query %s: error reply %r", selector, reply.payload)
    return [reply for reply in replies if reply.ok]


def format_lines(values: list[KeyValue], full: bool = False) -> list[str]:
    lines = []
    for item in values:
        if isinstance(item.value, str):
            text = item.value
        else:
            text = msgspec.json.encode(item.value).decode()
        if not full and len(text) > TEXT_WIDTH:
            text = text[: TEXT_WIDTH - 3] + "..."
        suffix = f"  ({item.encoding})" if item.encoding and "json" not in item.encoding else ""
        lines.append(f"{item.key} = {text}{suffix}")
    return lines


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
