"""What the gateway asks of the fleet: send a mission, abort a UAV's part, look up a
mission's targets. Each call blocks on Zenoh queries, so the gateway runs them off its
MAVLink loop (a worker thread) and answers the ground station when they return.

They reuse the mission manager's own code: the page's `MissionDesk` claims the mission
id and serves its targets exactly as `ground-cli send-targets` does; the abort is
`ground-cli abort --uav`'s MissionAbort, confirmed as it confirms it, by the UAV's own
state reporting the phase `aborted`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from enum import Enum, auto

from fleet.consensus.deadline import consensus_deadline
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.mission.phase import Phase
from fleet.mission.target_checks import DEFAULT_MAX_REACH_M, target_set_problems
from fleet.transport.bus import Bus
from ground.fleet_view import query_states
from ground.gui.commands import MissionDesk
from ground.mission_ack import wait_acknowledged
from ground.mission_commands import ABORT_CONFIRM_S
from ground.mission_control import (
    MissionError,
    mission_targets_of,
    send_abort,
)
from ground.mission_ids import rival_claims
from ground.send_command import DELIVERY_WAIT_S

log = logging.getLogger(__name__)

#: How often the abort's confirmation is looked for (each look is a state query).
CONFIRM_POLL_S = 0.2


class TeamChoice(Enum):
    """Who flies a mission uploaded to one UAV's system id (docs/mavlink.md)."""

    UAV = auto()  #: that UAV alone (the default)
    LIVE = auto()  #: every live UAV: the fleet assigns the items across them


@dataclass(frozen=True)
class SendOutcome:
    """A mission the fleet took (`mission` set), or why not (`problem`)."""

    mission: int | None
    team: tuple[int, ...] = ()
    problem: str | None = None
    sent: int | None = None  #: the id of a mission put but not acknowledged


class AbortResult(Enum):
    CONFIRMED = auto()
    NOT_ON_A_MISSION = auto()
    NOT_CONFIRMED = auto()


class FleetLink:
    def __init__(self, bus: Bus, space: KeySpace, query_timeout_s: float) -> None:
        self._bus = bus
        self._space = space
        self._timeout = query_timeout_s
        self._desk = MissionDesk(bus, space, lambda: None)

    def close(self) -> None:
        self._desk.close()

    def send_mission(
        self, uav: int, targets: tuple[Target, ...], choice: TeamChoice, live: list[int]
    ) -> SendOutcome:
        """Send `targets` to `uav`'s team (`choice`), after the checks `send-targets`
        makes (no targets within the acceptance radius of each other, none beyond reach),
        and wait for the team to acknowledge it (as `send-targets` does). `live`: the UAVs
        the gateway shows (its liveliness subscription), the vehicles the station sees."""
        if uav not in live:
            return SendOutcome(None, problem=f"UAV {uav} is not live")
        team = (uav,) if choice is TeamChoice.UAV else tuple(sorted(live))
        positions = {
            piccolo: (state.telemetry.gps.lat, state.telemetry.gps.lon)
            for piccolo, state in query_states(self._bus, self._space, self._timeout).items()
            if piccolo in team and state.telemetry is not None and state.telemetry.gps is not None
        }
        problems = target_set_problems(targets, positions, DEFAULT_MAX_REACH_M)
        if problems:
            return SendOutcome(None, team, problem=str(problems[0]))
        deadline_s = consensus_deadline(len(team))
        try:
            mission = self._desk.send(team, targets, deadline_s)
        except MissionError as error:
            return SendOutcome(None, team, problem=str(error))
        log.info("mission %d: %d items from MAVLink sent to %s", mission, len(targets), team)
        # Accepted means the team has it, not that it was put: a put the routers refuse
        # (another identity in a secure fleet) vanishes without an error, and a ground
        # that cannot see the fleet's missions may have chosen an id already in use.
        sent = MissionTargets(mission, team, targets, deadline_s=deadline_s)
        seen = wait_acknowledged(self._bus, self._space, sent, DELIVERY_WAIT_S)
        if (collision := seen.collision(sent)) is not None:
            return SendOutcome(None, team, problem=str(collision), sent=mission)
        missing = ", ".join(str(uav) for uav in team if uav not in seen.got)
        # A UAV that reports no digest (an older onboard) is believed on the id: ask
        # whether anything serves other targets under it.
        if not missing and rival_claims(self._bus, self._space, sent, self._timeout):
            missing = f"{', '.join(map(str, team))} (they hold another mission {mission})"
        if missing:
            return SendOutcome(
                None, team, problem=f"mission {mission} not acknowledged by {missing}", sent=mission
            )
        return SendOutcome(mission, team)

    def abort(self, uav: int) -> tuple[AbortResult, str]:
        """Abort `uav`'s part of its mission and wait for its state to say `aborted`."""
        state = query_states(self._bus, self._space, self._timeout).get(uav)
        if state is None or state.mission is None:
            return AbortResult.NOT_ON_A_MISSION, f"UAV {uav} is on no mission"
        mission = state.mission.mission
        if state.mission.phase == Phase.ABORTED:
            return AbortResult.CONFIRMED, f"mission {mission}: UAV {uav} aborted"
        send_abort(self._bus, self._space, mission, uav)
        deadline = time.monotonic() + max(ABORT_CONFIRM_S, self._timeout)
        while time.monotonic() < deadline:
            now = query_states(self._bus, self._space, self._timeout).get(uav)
            progress = now.mission if now is not None else None
            if progress is not None and progress.mission == mission:
                if progress.phase == Phase.ABORTED:
                    return AbortResult.CONFIRMED, f"mission {mission}: UAV {uav} aborted"
            elif progress is not None and progress.mission > mission:
                return AbortResult.NOT_CONFIRMED, f"UAV {uav} left for mission {progress.mission}"
            time.sleep(CONFIRM_POLL_S)
        return AbortResult.NOT_CONFIRMED, f"mission {mission}: UAV {uav} did not confirm the abort"

    def mission_targets(self, mission: int) -> MissionTargets | None:
        try:
            return mission_targets_of(self._bus, self._space, mission, self._timeout)
        except MissionError:
            return None
