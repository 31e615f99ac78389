"""`fleet replay`: put a recording's state back on Zenoh, as if the fleet were live.

The recorded messages are published again, `rate` times faster than recorded, under
another key prefix (`replay` by default) so a replay can never be mistaken for the
live fleet. Commands (missions, aborts, OPM, waypoint and track commands) are never
published, nor the channels the recorder made up (map fixes). So that the ground's
tools see the UAVs:

* each UAV's liveliness token `{prefix}/uav/{id}/alive` is declared while the
  recording has it alive (from its first telemetry when the token was not recorded);
* `{prefix}/uav/*/state` is served: each UAV's last recorded state, with the latest
  replayed telemetry in it. Before a UAV's first recorded state it is not answered.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field

import msgspec
import zenoh

from fleet.mission import key_registry as reg
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import UavState
from fleet.piccolo.telemetry import Telemetry
from fleet.recording import channels
from fleet.recording.reader import RecordedMessage, Recording
from fleet.transport import bus_codec

log = logging.getLogger(__name__)

DEFAULT_REPLAY_PREFIX = "replay"


def replayable(message: RecordedMessage) -> bool:
    """Whether a recorded message goes back on the bus (state yes; commands never)."""
    if channels.is_derived(message.schema_name) or channels.is_command(message.topic):
        return False
    return message.topic.count("/") >= 1


@dataclass
class ReplayStats:
    published: int = 0
    skipped: int = 0  #: commands and made-up channels
    bad: int = 0  #: recorded states or telemetry that do not decode


@dataclass
class Replayer:
    """Publishes `recording` on `session` under `prefix` at `rate` x real time."""

    session: zenoh.Session
    recording: Recording
    prefix: str = DEFAULT_REPLAY_PREFIX
    rate: float = 1.0
    stop: threading.Event = field(default_factory=threading.Event)
    stats: ReplayStats = field(default_factory=ReplayStats)
    _states: dict[int, UavState] = field(default_factory=dict)
    _telemetry: dict[int, Telemetry] = field(default_factory=dict)
    _tokens: dict[int, zenoh.LivelinessToken] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def space(self) -> KeySpace:
        """The keys the replay puts and serves: the recorded ones under `prefix`."""
        return KeySpace(self.prefix)

    def run(self) -> bool:
        """Replay to the end (True) or until `stop` is set (False)."""
        messages = self.recording.messages
        if not messages:
            return True
        queryable = self.session.declare_queryable(self.space.all_state, self._on_state_query)
        try:
            first = messages[0].log_time_ns
            started = time.monotonic()
            for message in messages:
                due = started + (message.log_time_ns - first) / 1e9 / self.rate
                if self.stop.wait(max(0.0, due - time.monotonic())):
                    return False
                self._replay(message)
            return True
        finally:
            queryable.undeclare()

    def hold(self, seconds: float) -> None:
        """Keep tokens and states served a while after the end (or until `stop`)."""
        self.stop.wait(seconds)

    def close(self) -> None:
        with self._lock:
            tokens = list(self._tokens.values())
            self._tokens.clear()
        for token in tokens:
            token.undeclare()

    # ---- one message ---------------------------------------------------------------------
    def _replay(self, message: RecordedMessage) -> None:
        if not replayable(message):
            self.stats.skipped += 1
            return
        key = channels.with_prefix(message.topic, self.prefix)
        parsed = self.space.parse(key)
        uav = int(parsed.uav) if parsed and parsed.uav and parsed.uav.isdigit() else None
        if uav is not None and parsed is not None:
            if parsed.spec is reg.ALIVE:
                self._set_alive(uav, message)
                return
            if parsed.spec is reg.STATE:
                self._keep_state(uav, message)
                return
            if parsed.spec is reg.TELEMETRY:
                self._keep_telemetry(uav, message)
        self.session.put(key, message.data, encoding=bus_codec.ENCODING)
        self.stats.published += 1

    def _set_alive(self, uav: int, message: RecordedMessage) -> None:
        value = message.value()
        alive = isinstance(value, dict) and value.get("alive") is True
        with self._lock:
            token = self._tokens.pop(uav, None)
            if alive:
                self._tokens[uav] = token or self._declare_token(uav)
        if token is not None and not alive:
            token.undeclare()

    def _declare_token(self, uav: int) -> zenoh.LivelinessToken:
        return self.session.liveliness().declare_token(self.space.alive(uav))

    def _keep_state(self, uav: int, message: RecordedMessage) -> None:
        try:
            state = msgspec.json.decode(message.data, type=UavState)
        except (msgspec.ValidationError, msgspec.DecodeError, UnicodeDecodeError) as error:
            self.stats.bad += 1
            log.warning("recorded state of UAV %d not replayed: %s", uav, error)
            return
        with self._lock:
            self._states[uav] = state

    def _keep_telemetry(self, uav: int, message: RecordedMessage) -> None:
        try:
            telemetry = msgspec.json.decode(message.data, type=Telemetry)
        except (msgspec.ValidationError, msgspec.DecodeError, UnicodeDecodeError):
            self.stats.bad += 1
            return
        with self._lock:
            self._telemetry[uav] = telemetry
            if uav not in self._tokens:
                self._tokens[uav] = self._declare_token(uav)

    # ---- the state queryable (Zenoh threads) ---------------------------------------------
    def _on_state_query(self, query: zenoh.Query) -> None:
        with self._lock:
            states = dict(self._states)
            telemetry = dict(self._telemetry)
        for uav, state in states.items():
            key = self.space.state(uav)
            if not zenoh.KeyExpr(key).intersects(query.key_expr):
                continue
            latest = telemetry.get(uav, state.telemetry)
            answer = msgspec.structs.replace(state, telemetry=latest)
            query.reply(key, bus_codec.encode(answer), encoding=bus_codec.ENCODING)
