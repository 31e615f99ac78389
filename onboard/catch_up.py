"""Catching up with what the team decided while this UAV was away: when to ask.

Asked at start, when a teammate (re)appears (this UAV may be the one that was away:
frozen, cut off), and when the module's own clock shows it was suspended; at most once
every CATCH_UP_INTERVAL_S otherwise, a request too soon deferred, not dropped.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

log = logging.getLogger(__name__)

#: At most one catch-up query (live missions, the teammates' assignments) this often.
CATCH_UP_INTERVAL_S = 5.0
#: Two ticks this far apart (s; the main loop ticks every 0.25 s) mean the module itself
#: was suspended (SIGSTOP, a starved machine): it catches up at once, and again after
#: each of these delays (s), for its bus session may still be working off the backlog
#: or reconnecting, and a query then goes unanswered.
SUSPENDED_S = 2.0
CATCH_UP_AFTER_SUSPENSION_S = (1.0, 3.0)


class CatchUpOutputs(Protocol):
    def fetch_assignments(self, mission: int) -> None: ...
    def fetch_missions(self) -> None: ...


@dataclass
class CatchUp:
    outputs: CatchUpOutputs
    #: The mission in progress, whose assignments a catch-up asks for too (None: none).
    current_mission: Callable[[], int | None]
    _caught_up_at: float = -math.inf
    _ticked_at: float | None = None
    _resumed_at: float = -math.inf  #: when a suspension of this module was last noticed
    _due: list[float] = field(default_factory=list)

    def request(self, now: float, *, force: bool = False) -> None:
        """Ask for the live missions and the current one's assignments: at start, when
        a teammate (re)appears, for this UAV may be the one that was away (frozen, cut
        off), and (`force`) when its own clock shows it was suspended. Brings it in line
        with what was decided meanwhile; else at most once every CATCH_UP_INTERVAL_S."""
        if not force and now - self._caught_up_at < CATCH_UP_INTERVAL_S:
            # Deferred, not dropped: a teammate reappearing just after a catch-up may
            # mean this UAV's own session has only now reconnected, and that catch-up's
            # queries went nowhere.
            due = self._caught_up_at + CATCH_UP_INTERVAL_S
            if due not in self._due:
                self._due = sorted([*self._due, due])
            return
        self._caught_up_at = now
        self.outputs.fetch_missions()
        mission = self.current_mission()
        if mission is not None:
            self.outputs.fetch_assignments(mission)

    def _ticks_missed(self, now: float) -> bool:
        """The main loop has not ticked for SUSPENDED_S: the module was suspended."""
        return self._ticked_at is not None and now - self._ticked_at > SUSPENDED_S

    def resumed(self, now: float) -> bool:
        """Whether this module was suspended just before `now`: ticks missed (an event
        may be handled before the first tick after it), or the tick noticed it within
        the last catch-ups' span."""
        return self._ticks_missed(now) or now - self._resumed_at <= CATCH_UP_AFTER_SUSPENSION_S[-1]

    def tick(self, now: float) -> bool:
        """Run the catch-ups due; True if this tick noticed that the module was suspended."""
        suspended = self._ticks_missed(now)
        if suspended:
            assert self._ticked_at is not None
            self._resumed_at = now
            # Frozen shorter than Zenoh's lease, no teammate seemed to come back, and
            # what was published meanwhile may be lost: ask for it.
            log.info("no tick for %.1f s: catching up", now - self._ticked_at)
            self.request(now, force=True)
            self._due = [now + delay for delay in CATCH_UP_AFTER_SUSPENSION_S]
        elif self._due and now >= self._due[0]:
            self._due.pop(0)
            self.request(now, force=True)
        self._ticked_at = now
        return suspended
