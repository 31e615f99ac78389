"""The onboard module's Zenoh edge: presence, subscriptions, queryables, publications.

Every callback only decodes and hands an event to `sink`; the main loop does the rest,
so no Zenoh thread ever waits on the module. Queryables use channel handlers polled
by the main loop, so a command's reply can wait for the autopilot's echo.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec
import zenoh

from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    UavResult,
)
from fleet.transport.bus_codec import ENCODING, BadMessage, decode, encode

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BusEvent:
    """Something that arrived over Zenoh: a decoded message, or a presence change."""

    key: str
    message: Any  # one of the messages in fleet.mission.messages, or a bool for presence


Sink = Callable[[BusEvent], None]

_SUBSCRIPTIONS: tuple[tuple[str, type[msgspec.Struct]], ...] = (
    (keys.ALL_MISSION_TARGETS, MissionTargets),
    (keys.ALL_MISSION_RESULTS, UavResult),
    (f"{keys.PREFIX}/mission/*/assignment/*", AssignmentReport),
    (keys.ALL_MISSION_ABORTS, MissionAbort),
)


class ZenohNode:
    def __init__(self, uav_id: int, config: zenoh.Config, sink: Sink) -> None:
        self.uav_id = uav_id
        self.sink = sink
        self.session = zenoh.open(config)
        self._declared: list[Any] = []
        try:
            self._declare()
        except Exception:
            self.session.close()
            raise

    def _declare(self) -> None:
        session = self.session
        self.token = session.liveliness().declare_token(keys.alive(self.uav_id))
        self._declared.append(
            session.liveliness().declare_subscriber(keys.ALL_ALIVE, self._on_presence, history=True)
        )
        subscriptions: tuple[tuple[str, type[msgspec.Struct]], ...] = (
            (keys.opm(self.uav_id), OpmCommand),
            *_SUBSCRIPTIONS,
        )
        for key, kind in subscriptions:
            self._declared.append(session.declare_subscriber(key, self._decoder(kind)))
        self.state_queries = session.declare_queryable(keys.state(self.uav_id))
        self.command_queries = session.declare_queryable(keys.command(self.uav_id, "*"))
        self.mission_queries = session.declare_queryable(f"{keys.PREFIX}/mission/*/**")

    def _on_presence(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        try:
            uav = keys.uav_id_of(key)
        except ValueError:
            return
        self.sink(BusEvent(key, (uav, sample.kind == zenoh.SampleKind.PUT)))

    def _decoder(self, kind: type[msgspec.Struct]) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            try:
                message = decode(sample.payload.to_bytes(), kind, key)
            except BadMessage as error:
                log.warning("dropped: %s", error)
                return
            self.sink(BusEvent(key, message))

        return on_sample

    def publish(self, key: str, message: msgspec.Struct) -> None:
        self.session.put(key, encode(message), encoding=ENCODING)

    def fetch(self, selector: str, kind: type[msgspec.Struct], timeout: float = 1.0) -> None:
        """Query `selector`; replies come back through the sink like publications."""
        decoder = self._decoder(kind)

        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                decoder(reply.ok)

        self.session.get(selector, on_reply, timeout=timeout)

    def close(self) -> None:
        for declared in self._declared:
            declared.undeclare()
        for queryable in (self.state_queries, self.command_queries, self.mission_queries):
            queryable.undeclare()
        self.token.undeclare()
        self.session.close()


def reply(query: zenoh.Query, key: str, message: msgspec.Struct) -> None:
    query.reply(key, encode(message), encoding=ENCODING)
