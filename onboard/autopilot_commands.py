"""Autopilot commands confirmed by their echo, retried, or reported failed.

The Piccolo echoes a WAYPOINT it stored and reports the TRACK it switched to (docs/protocol.md,
the autopilot packets): that echo is the only confirmation a sender gets. A command is resent
until its echo arrives or `max_attempts` are spent; a mission's own writes are resent
until their echo arrives or the mission cancels them (`persistent`), so a link outage
delays them but never loses them. The interval between attempts follows the echo
latency measured on this link (`RETRY_LATENCY_FACTOR` times its smoothed value, never
under `retry_interval`): a slow link gets fewer resends, not false failures.
Pure: time comes in as `now`, bytes go out through the `send` callable.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

from fleet.mission.messages import CommandResult
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint, encode_waypoint

log = logging.getLogger(__name__)

AutopilotCommand = Waypoint | Track
Completion = Callable[[CommandResult], None]


def echo_confirms(command: AutopilotCommand, echo: AutopilotCommand) -> bool:
    """True when `echo` is the autopilot's confirmation of `command` (compared on the wire)."""
    if isinstance(command, Track):
        return isinstance(echo, Track) and echo.waypoint == command.waypoint
    return isinstance(echo, Waypoint) and encode_waypoint(echo) == encode_waypoint(command)


#: Resend after this many times the smoothed echo latency (the floor is `retry_interval`).
RETRY_LATENCY_FACTOR = 4.0
#: Never wait longer than this between two attempts.
MAX_RETRY_INTERVAL = 5.0
#: Weight of the newest echo latency in the smoothed value.
LATENCY_SMOOTHING = 0.2


@dataclass
class _Pending:
    command: AutopilotCommand
    on_done: Completion
    attempts: int
    next_try: float
    sent_at: float
    persistent: bool


@dataclass
class CommandTracker:
    send: Callable[[AutopilotCommand], None]
    retry_interval: float = 0.5
    max_attempts: int = 4
    #: Smoothed seconds from a command's last sending to its echo; None before any echo.
    latency: float | None = None
    _pending: list[_Pending] = field(default_factory=list)

    def interval(self) -> float:
        """Seconds between two attempts, from the echo latency measured so far."""
        if self.latency is None:
            return self.retry_interval
        return min(
            MAX_RETRY_INTERVAL, max(self.retry_interval, RETRY_LATENCY_FACTOR * self.latency)
        )

    def submit(
        self,
        command: AutopilotCommand,
        now: float,
        on_done: Completion,
        *,
        persistent: bool = False,
    ) -> None:
        """Send `command` and resend it until echoed; `persistent`: with no attempt limit
        (until echoed, superseded or cancelled)."""
        # A newer command for the same waypoint (or a newer track) replaces the old one.
        for pending in list(self._pending):
            if _same_target(pending.command, command):
                self._pending.remove(pending)
                pending.on_done(CommandResult(False, "superseded", pending.attempts))
        self.send(command)
        self._pending.append(_Pending(command, on_done, 1, now + self.interval(), now, persistent))

    def on_echo(self, echo: AutopilotCommand, now: float) -> None:
        for pending in list(self._pending):
            if echo_confirms(pending.command, echo):
                self._pending.remove(pending)
                self._measure(now - pending.sent_at)
                pending.on_done(CommandResult(True, "confirmed by the autopilot", pending.attempts))

    def _measure(self, latency: float) -> None:
        if latency < 0:
            return
        if self.latency is None:
            self.latency = latency
        else:
            self.latency += LATENCY_SMOOTHING * (latency - self.latency)

    def tick(self, now: float) -> None:
        for pending in list(self._pending):
            if now < pending.next_try:
                continue
            if not pending.persistent and pending.attempts >= self.max_attempts:
                self._pending.remove(pending)
                log.warning("no echo for %r after %d attempts", pending.command, pending.attempts)
                pending.on_done(
                    CommandResult(
                        False, f"no echo after {pending.attempts} attempts", pending.attempts
                    )
                )
                continue
            pending.attempts += 1
            pending.next_try = now + self.interval()
            pending.sent_at = now
            self.send(pending.command)

    def cancel_all(self, reason: str) -> None:
        pending, self._pending = self._pending, []
        for item in pending:
            item.on_done(CommandResult(False, reason, item.attempts))

    def cancel_where(self, which: Callable[[AutopilotCommand], bool], reason: str) -> None:
        """Cancel the pending commands `which` picks; the others go on."""
        cancelled = [item for item in self._pending if which(item.command)]
        self._pending = [item for item in self._pending if not which(item.command)]
        for item in cancelled:
            item.on_done(CommandResult(False, reason, item.attempts))

    @property
    def pending(self) -> int:
        return len(self._pending)


def _same_target(a: AutopilotCommand, b: AutopilotCommand) -> bool:
    if isinstance(a, Track) and isinstance(b, Track):
        return True
    return isinstance(a, Waypoint) and isinstance(b, Waypoint) and a.index == b.index
