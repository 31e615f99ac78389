"""Watching a running fleet: what `fleet up` does between its start and its stop.

A child that is not essential (a UAV's onboard module, a router of a mesh) may die and
the fleet flies on, as a fleet of one container per UAV would: its death is told once
(which child, its exit status, the last lines of its log) and, with a restart policy,
it is started again after a back-off that doubles at each death of the same child. An
essential child (the ground's router, the simulator every aircraft's link runs
through, the recorder) dying ends the run. A UAV whose telemetry stops reaching the
fleet's recorder while the fleet's other streams flow is told once (and again if it
stops again after it came back).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from fleet.launch.children import Child
from fleet.launch.launcher import Fleet, LaunchError
from fleet.recording.streams import Stall

log = logging.getLogger(__name__)

#: How often the children are looked at, seconds.
POLL_S = 0.5


@dataclass(frozen=True)
class RestartPolicy:
    """Restart a dead non-essential child after `first_delay_s`, doubling per death of
    the same child up to `max_delay_s`."""

    first_delay_s: float = 1.0
    max_delay_s: float = 30.0

    def delay(self, deaths: int) -> float:
        """The back-off before the restart that follows the `deaths`-th death (1, 2, ...)."""
        return min(self.max_delay_s, self.first_delay_s * 2.0 ** max(0, deaths - 1))


@dataclass(frozen=True)
class ChildLost:
    """A non-essential child that died: what the operator is told."""

    child: Child
    status: int | None
    #: When it will be started again (monotonic seconds), None if it will not.
    restart_at: float | None


@dataclass
class _Supervision:
    fleet: Fleet
    policy: RestartPolicy | None
    on_lost: Callable[[ChildLost], None]
    deaths: dict[str, int] = field(default_factory=dict)
    #: Child name -> (the dead child, when to restart it).
    pending: dict[str, tuple[Child, float]] = field(default_factory=dict)
    told: set[int] = field(default_factory=set)  #: pids whose death was told
    on_stall: Callable[[Stall], None] | None = None
    stalled: set[int] = field(default_factory=set)  #: UAVs whose stopped telemetry was told

    def look_at_streams(self) -> None:
        recorder = self.fleet.recorder
        if recorder is None or self.on_stall is None:
            return
        stalls = recorder.streams.stalled()
        for stall in stalls:
            if stall.uav not in self.stalled:
                self.on_stall(stall)
        self.stalled = {stall.uav for stall in stalls}

    def look(self, now: float) -> Child | None:
        """Handle the non-essential deaths and restarts due; the first dead essential
        child, if any."""
        for child in self.fleet.dead_children():
            if child.essential:
                return child
            if child.pid not in self.told:
                self._lost(child, now)
        for name, (child, when) in list(self.pending.items()):
            if now >= when:
                del self.pending[name]
                self._restart(child)
        return None

    def _lost(self, child: Child, now: float) -> None:
        self.told.add(child.pid)
        deaths = self.deaths[child.name] = self.deaths.get(child.name, 0) + 1
        restart_at = None
        if self.policy is not None and child.argv:
            restart_at = now + self.policy.delay(deaths)
            self.pending[child.name] = (child, restart_at)
        self.on_lost(ChildLost(child, child.process.returncode, restart_at))

    def _restart(self, child: Child) -> None:
        try:
            again = self.fleet.restart(child)
        except (LaunchError, OSError) as error:
            log.error("could not restart %s: %s", child.name, error)
            return
        log.info("restarted %s (pid %d)", again.name, again.pid)


def _log_lost(lost: ChildLost) -> None:
    log.warning("%s exited with status %s; the fleet goes on", lost.child.name, lost.status)


def _log_stall(stall: Stall) -> None:
    log.warning("%s", stall)


def supervise(
    fleet: Fleet,
    stop: threading.Event,
    on_death: Callable[[Child], None] | None = None,
    on_lost: Callable[[ChildLost], None] = _log_lost,
    restart: RestartPolicy | None = None,
    on_stall: Callable[[Stall], None] = _log_stall,
) -> bool:
    """Block until `stop` is set (True) or an essential child dies (False, after
    `on_death`); non-essential deaths go to `on_lost` and, with `restart`, are restarted;
    a UAV's telemetry that stops reaching the recorder goes to `on_stall`."""
    supervision = _Supervision(fleet, restart, on_lost, on_stall=on_stall)
    while not stop.wait(POLL_S):
        supervision.look_at_streams()
        dead = supervision.look(time.monotonic())
        if dead is not None:
            if on_death is not None:
                on_death(dead)
            return False
    return True
