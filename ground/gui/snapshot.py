"""What the page is pushed, and how often: the fleet snapshot and its coalescing.

The page gets one JSON snapshot per push: every UAV as `ground-cli uavs --json` shows
it (`UavView.to_json`) plus its recent track and its link/module flags, the current
mission as `send-targets --json` reports it plus each target's state, and the status
messages that arrived since the previous push.

Telemetry arrives at any rate from any number of UAVs, on Zenoh's threads; the page
must not be pushed at that rate. Zenoh callbacks only *mark* the snapshot dirty (on
the event loop, through `loop.call_soon_threadsafe`), and one task pushes at most
`rate_hz` snapshots a second however many marks arrived: the cost to the page is
bounded by the rate and the fleet size, never by the telemetry rate.

Everything here runs on the event loop's thread, except `Coalescer.mark_threadsafe`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from fleet.mission.phase import Severity
from ground.alerts import Alerts, StatusRecord
from ground.fleet_view import UavView
from ground.mission_outcome import MissionOutcome

log = logging.getLogger(__name__)

#: Pushes a second at most (the issue asks for 5-10 Hz).
DEFAULT_RATE_HZ = 5.0
#: Positions kept per UAV for its trail on the map.
TRAIL_LENGTH = 150
#: A trail point is added only when the UAV moved at least this far (degrees, ~10 m).
TRAIL_STEP_DEG = 1e-4
#: Telemetry older than this (s) shows the UAV's link as lost.
LINK_LOST_AFTER_S = 3.0
#: Status messages kept for a page that connects later.
STATUS_HISTORY = 500


class TargetState(StrEnum):
    """A mission target as the page shows it."""

    PENDING = "pending"  #: sent, the team has not committed yet
    ASSIGNED = "assigned"
    REACHED = "reached"
    UNSERVED = "unserved"  #: every UAV committed and none took it
    ABORTED = "aborted"  #: the mission, or its holder alone, was aborted short of it
    FAILED = "failed"  #: its holder could not fly it
    PREEMPTED = "preempted"  #: its holder's autopilot left the route short of it
    REMOVED = "removed"  #: taken off the mission in flight: never flown from then on


#: States in which a target has no live claim: no assignment line, no ETA.
_ENDED = frozenset({TargetState.ABORTED, TargetState.FAILED, TargetState.PREEMPTED})


@dataclass(frozen=True)
class StatusEntry:
    seq: int
    time: float  #: wall clock, seconds since the epoch
    uav: int
    text: str
    severity: Severity

    def to_json(self) -> dict[str, Any]:
        return {
            "seq": self.seq,
            "time": self.time,
            "uav": self.uav,
            "text": self.text,
            "severity": str(self.severity),
        }


def target_states(
    outcome: MissionOutcome, views: dict[int, UavView], reached: set[int], aborted: bool
) -> list[dict[str, Any]]:
    """Each target's state, who it is assigned to and that UAV's ETA.

    `reached` holds the UAVs seen to reach their target in this mission (sticky: a
    UAV's phase moves on after it reached). A target whose holder's part ended short of
    it (its phase noted in `outcome`: aborted alone, failed, preempted) shows that, with
    the UAV and no ETA: nobody is flying to it.
    """
    owner = outcome.holders()
    reached_by = outcome.reached_by()
    latest = outcome.latest()
    # With queues a UAV reaches several targets: only its outcomes say which.
    queued = latest is not None and bool(latest.queues)
    states = []
    for index in range(len(outcome.targets)):
        if index in outcome.removed:
            states.append({"index": index, "state": str(TargetState.REMOVED), "uav": None})
            continue
        uav = reached_by.get(index, owner.get(index))
        view = views.get(uav) if uav is not None else None
        says_reached = (
            view is not None and view.mission == outcome.mission and view.phase == "reached"
        )
        ended = outcome.ended_short(uav, index) if uav is not None else None
        sticky = not queued and uav is not None and (uav in reached or says_reached)
        if index in reached_by or sticky:
            state = TargetState.REACHED
        elif uav is None and outcome.committed:
            state = TargetState.UNSERVED
        elif ended is not None:
            state = TargetState(str(ended[0]))
        elif aborted:
            state = TargetState.ABORTED
        else:
            state = TargetState.PENDING if uav is None else TargetState.ASSIGNED
        report = outcome.assignments.get(uav) if uav is not None else None
        eta = report.eta_s if report is not None and state not in _ENDED else None
        place = outcome.place(index) if queued else None
        entry: dict[str, Any] = {"index": index, "state": str(state), "uav": uav, "eta_s": eta}
        if place is not None:
            entry["place"] = place[0]
            if state not in _ENDED:
                entry["eta_s"] = place[1]
        if ended is not None and state in _ENDED:
            entry["reason"] = ended[1]
        states.append(entry)
    return states


@dataclass
class GuiModel:
    """The page's picture between pushes: trails, status log, mission bookkeeping."""

    trails: dict[int, deque[tuple[float, float]]] = field(default_factory=dict)
    statuses: deque[StatusEntry] = field(default_factory=lambda: deque(maxlen=STATUS_HISTORY))
    _seq: int = 0
    _pushed_seq: int = 0
    #: (mission, uav) pairs seen reached
    reached: set[tuple[int, int]] = field(default_factory=set)
    aborted: set[int] = field(default_factory=set)
    #: The warnings and errors the page keeps in view (`ground.alerts`).
    alerts: Alerts = field(default_factory=Alerts)

    def add_status(self, record: StatusRecord) -> None:
        """A status message as the ground received it; its kind says its severity."""
        self._seq += 1
        entry = StatusEntry(self._seq, record.time, record.uav, record.text, record.severity)
        self.statuses.append(entry)
        self.alerts.add(record)

    def alerts_json(self) -> list[dict[str, Any]]:
        """The pinned warnings and errors, oldest first."""
        return [
            {"time": a.time, "uav": a.uav, "text": a.text, "severity": str(a.severity)}
            for a in self.alerts.pinned()
        ]

    def note_views(self, views: list[UavView]) -> None:
        """Extend the trails, and remember which UAVs reached their target."""
        for view in views:
            if view.lat is not None and view.lon is not None:
                trail = self.trails.setdefault(view.id, deque(maxlen=TRAIL_LENGTH))
                if (
                    not trail
                    or max(abs(trail[-1][0] - view.lat), abs(trail[-1][1] - view.lon))
                    >= TRAIL_STEP_DEG
                ):
                    trail.append((view.lat, view.lon))
            if view.mission is not None and view.phase == "reached":
                self.reached.add((view.mission, view.id))

    def uav_json(self, view: UavView) -> dict[str, Any]:
        data = view.to_json()
        age = view.telemetry_age_s
        data["link_lost"] = age is not None and age > LINK_LOST_AFTER_S
        data["trail"] = [list(point) for point in self.trails.get(view.id, ())]
        return data

    def mission_json(
        self, outcome: MissionOutcome | None, views: list[UavView]
    ) -> dict[str, Any] | None:
        if outcome is None:
            return None
        for view in views:
            # What each UAV reports decides its target's state and the mission's success.
            if view.id in outcome.team and view.phase is not None:
                outcome.note_phase(view.id, view.phase, view.reason, view.mission)
        data = outcome.to_json()
        by_id = {view.id: view for view in views}
        reached = {uav for mission, uav in self.reached if mission == outcome.mission}
        aborted = outcome.mission in self.aborted
        data["aborted"] = aborted
        data["results_received"] = len(outcome.results.keys() & set(outcome.team))
        data["target_states"] = target_states(outcome, by_id, reached, aborted)
        return data

    def new_statuses(self) -> list[dict[str, Any]]:
        """The statuses since the previous call, oldest first."""
        fresh = [s.to_json() for s in self.statuses if s.seq > self._pushed_seq]
        self._pushed_seq = self._seq
        return fresh

    def all_statuses(self) -> list[dict[str, Any]]:
        return [s.to_json() for s in self.statuses]


class Coalescer:
    """Runs `push` at most `rate_hz` times a second, and only after a `mark`."""

    def __init__(self, push: Callable[[], Awaitable[None]], rate_hz: float) -> None:
        self._push = push
        self._period_s = 1.0 / rate_hz
        self._dirty = asyncio.Event()
        # Made on the loop that runs it: callbacks need it before the first push.
        self._loop = asyncio.get_running_loop()
        self.pushes = 0
        self.marks = 0

    def mark(self) -> None:
        """Something changed (event loop thread)."""
        self.marks += 1
        self._dirty.set()

    def mark_threadsafe(self) -> None:
        """Something changed (any thread, e.g. a Zenoh callback)."""
        # A callback racing the loop's close at shutdown has nothing left to tell.
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(self.mark)

    async def run(self) -> None:
        while True:
            await self._dirty.wait()
            self._dirty.clear()
            try:
                await self._push()
            except Exception:
                # A push must never end the loop that feeds every page.
                log.exception("pushing the snapshot failed")
            self.pushes += 1
            await asyncio.sleep(self._period_s)
