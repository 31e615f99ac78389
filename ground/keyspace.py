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
import zenoh

from fleet.mission import keys
from ground.session import decode_value, live_tokens, query

log = logging.getLogger(__name__)


def default_expr() -> str:
    """Everything under the key prefix."""
    return f"{keys.PREFIX}/**"


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
    session: zenoh.Session,
    expr: str,
    *,
    window_s: float,
    timeout_s: float,
    admin: bool,
) -> list[KeyValue]:
    """Every key under `expr` with its latest value, sorted by key."""
    found: dict[str, KeyValue] = {}
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        payload = sample.payload.to_bytes()
        encoding = str(sample.encoding)
        value = KeyValue(
            str(sample.key_expr), encoding, decode_value(payload, encoding), "subscription"
        )
        with lock:
            found[value.key] = value

    # Subscribe before querying, so a sample published meanwhile is not lost; samples
    # that arrive after the query are newer than its replies and replace them.
    with session.declare_subscriber(expr, on_sample):
        for reply in query(session, expr, timeout_s):
            value = KeyValue(
                reply.key, reply.encoding, decode_value(reply.payload, reply.encoding), "query"
            )
            with lock:
                found.setdefault(value.key, value)
        for key in live_tokens(session, expr, timeout_s):
            with lock:
                found.setdefault(key, KeyValue(key, "", "<liveliness token>", "liveliness"))
        deadline = time.monotonic() + window_s
        while (remaining := deadline - time.monotonic()) > 0:
            time.sleep(min(remaining, 0.1))
    if admin and not expr.startswith("@"):
        for reply in query(session, ADMIN_EXPR, timeout_s):
            found.setdefault(
                reply.key,
                KeyValue(
                    reply.key, reply.encoding, decode_value(reply.payload, reply.encoding), "admin"
                ),
            )
    with lock:
        return [found[key] for key in sorted(found)]


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
