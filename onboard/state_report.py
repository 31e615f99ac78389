"""Reporting the UAV's state: status messages on change, the state on its key.

A status message goes out when something happens (on the bus and, if wired, to the
ground over the payload port); the state (`UavState`) goes out every 1 / rate_hz s
(0: only on query) and answers state queries.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Protocol

import msgspec

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionProgress, StatusText, UavResult, UavState
from fleet.mission.phase import Phase, Severity
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import Telemetry

log = logging.getLogger(__name__)


class Say(Protocol):
    """How a role says something: a status message of `kind`, at `now`, about `mission`
    and its `target` index when it concerns them."""

    def __call__(
        self,
        kind: StatusKind,
        text: str,
        now: float,
        *,
        mission: int | None = None,
        target: int | None = None,
    ) -> None: ...


class ReportOutputs(Protocol):
    def publish(self, key: str, message: msgspec.Struct) -> None: ...
    def send_ground(self, message: StatusText | UavResult) -> None: ...


@dataclass
class StateReport:
    uav_id: int
    key_space: KeySpace
    outputs: ReportOutputs
    #: How often the UAV's state is published on its state key (0: only on query).
    rate_hz: float = 1.0
    last_status: str | None = None
    _last_state_at: float = -math.inf

    def status(
        self,
        kind: StatusKind,
        text: str,
        now: float,
        *,
        mission: int | None = None,
        target: int | None = None,
    ) -> None:
        """A status message: sent on change only (the periodic report is the state)."""
        self.last_status = text
        message = StatusText(text, kind, mission, target)
        (log.info if message.severity == Severity.INFO else log.warning)("%s", text)
        self.outputs.publish(self.key_space.status(self.uav_id), message)
        self.outputs.send_ground(message)

    def due(self, now: float) -> bool:
        """Whether the periodic state report is due."""
        return self.rate_hz > 0 and now - self._last_state_at >= 1 / self.rate_hz

    def publish_state(self, state: UavState, now: float) -> None:
        """The UAV's state on its state key: the periodic report, kept out of the status box."""
        self._last_state_at = now
        self.outputs.publish(self.key_space.state(self.uav_id), state)

    def state(
        self,
        *,
        enabled: bool,
        tracked_waypoint: int | None,
        telemetry: Telemetry | None,
        progress: MissionProgress | None,
        shown: tuple[Phase, str | None],
    ) -> UavState:
        """The state to report; `shown` is the phase shown and why (`overall_phase`)."""
        phase, reason = shown
        return UavState(
            uav=self.uav_id,
            enabled=enabled,
            status_rate_hz=self.rate_hz,
            tracked_waypoint=tracked_waypoint,
            telemetry=telemetry,
            link=None,
            mission=progress,
            last_status=self.last_status,
            phase=phase,
            reason=reason,
        )


def overall_phase(
    *,
    enabled: bool,
    silent_s: float | None,
    link_lost: bool,
    mission: tuple[Phase, str | None] | None,
) -> tuple[Phase, str | None]:
    """The phase the UAV shows: `off` and `link_lost` outrank the mission's phase.

    `silent_s`: seconds since the latest telemetry (None: none ever came); `mission`: the
    current mission's phase and reason (None: no mission)."""
    if not enabled:
        return Phase.OFF, "the onboard planning module is turned off"
    if silent_s is not None and link_lost:
        return Phase.LINK_LOST, f"no telemetry from the autopilot for {silent_s:.1f} s"
    if mission is None:
        return Phase.IDLE, None
    return mission
