"""The onboard planning module's logic: what to do with each event, and when.

Events arrive here whichever way they came (Zenoh, or the payload port from a ground
station reachable only over the Piccolo radio): one code path handles a command.
What the module does goes out through `Outputs`, which the process wires to the link
adapter and the bus edge, and which unit tests replace with a recorder. No I/O here.

`OnboardCore` hands each event to the role it is for, each a class of its own:
watching the autopilot link (onboard.link_watch), flying a target
(onboard.target_flight), taking part in a mission (onboard.mission_participation,
with onboard.catch_up), and reporting state and status (onboard.state_report). Every
phase is what the module observed (docs/lifecycle.md), moved by the one table in
`fleet.mission.lifecycle` (onboard.mission_phase).
"""

from __future__ import annotations

import math
from typing import Protocol

from fleet.consensus.mission_round import MissionRound, Settled
from fleet.consensus.targets_digest import targets_digest
from fleet.geo.wind import Wind
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    OpmCommand,
    PlanProposal,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.approach_plan import ApproachPlan, Planner
from onboard.autopilot_commands import AutopilotCommand, CommandTracker, Completion
from onboard.catch_up import CATCH_UP_INTERVAL_S
from onboard.link_watch import LINK_LOST_S, LinkWatch
from onboard.mission_participation import MissionOutputs, MissionParticipation
from onboard.mission_phase import MissionPhase
from onboard.plan_proposer import PlanProposer
from onboard.state_report import ReportOutputs, Say, StateReport, overall_phase
from onboard.target_flight import (
    CONFIRM_LIMIT_S,
    LINK_RELEASE_S,
    TARGET_WAYPOINT,
    FlightNews,
    FlightOutputs,
    TargetFlight,
)
from onboard.team_presence import LIVELINESS_GRACE_S, TeamPresence
from onboard.zone_watch import ZoneWatch

# Imported from here by the process, its CLI and the tests: the module's settings.
__all__ = [
    "CATCH_UP_INTERVAL_S",
    "CONFIRM_LIMIT_S",
    "LINK_LOST_S",
    "LINK_RELEASE_S",
    "LIVELINESS_GRACE_S",
    "TARGET_WAYPOINT",
    "OnboardCore",
    "Outputs",
    "Planner",
]


class Outputs(MissionOutputs, FlightOutputs, ReportOutputs, Protocol):
    """Where the module's decisions go: everything each of its roles sends."""


class OnboardCore:
    """One UAV's module logic: the dispatcher of its events to its roles."""

    def __init__(
        self,
        uav_id: int,
        outputs: Outputs,
        planner: Planner,
        planning_budget_s: float = 2.0,
        enabled: bool = True,
        status_rate_hz: float = 1.0,
        confirm_limit_s: float = CONFIRM_LIMIT_S,
        link_release_s: float = LINK_RELEASE_S,
        liveliness_grace_s: float = LIVELINESS_GRACE_S,
        key_space: KeySpace = DEFAULT_SPACE,
        fresh_replans: bool = True,
        vouch_teammates: bool = False,
        propose: bool = False,
    ) -> None:
        """`fresh_replans`: every re-plan is solved again from the survivors' fresh
        times (fleet.consensus.resolve); off, it is the append rule's, committed at once
        (what a re-plan commits when their times are missing). `vouch_teammates` (the
        secure profile): a teammate's liveliness token counts only once the teammate
        spoke for itself (`on_spoke`; onboard.team_presence). `propose`: this UAV
        proposes plans for the missions that name it (onboard.plan_proposer)."""
        self.uav_id = uav_id
        self.planner = planner
        self.report = StateReport(uav_id, key_space, outputs, status_rate_hz)
        self._outputs = outputs
        self._telemetry_key = key_space.telemetry(uav_id)
        say = self.report.status
        self.life = MissionPhase()
        self.link = LinkWatch(say)
        self.flight = TargetFlight(
            uav_id,
            key_space,
            outputs,
            self.life,
            self.link,
            say,
            enabled=enabled,
            confirm_limit_s=confirm_limit_s,
            link_release_s=link_release_s,
        )
        self.zone_watch = ZoneWatch(say)
        self.mission = MissionParticipation(
            uav_id,
            key_space,
            outputs,
            ApproachPlan(planner, planning_budget_s),
            TeamPresence(uav_id, liveliness_grace_s, vouch=vouch_teammates),
            self.life,
            self.link,
            self.flight,
            say,
            fresh_replans=fresh_replans,
            proposer=PlanProposer(uav_id, say) if propose else None,
        )

    # ---- what the roles hold, read by the process and the tests ----------------------------
    @property
    def enabled(self) -> bool:
        return self.flight.enabled

    @property
    def status_rate_hz(self) -> float:
        return self.report.rate_hz

    @status_rate_hz.setter
    def status_rate_hz(self, rate_hz: float) -> None:
        self.report.rate_hz = rate_hz

    @property
    def phase(self) -> Phase:
        return self.life.phase

    @property
    def round(self) -> MissionRound | None:
        return self.mission.round

    @property
    def settled(self) -> Settled | None:
        return self.mission.settled

    @property
    def commands(self) -> CommandTracker:
        return self.flight.commands

    @property
    def wind(self) -> Wind:
        """The smoothed wind (onboard.planner.wind_estimate): the one the module plans with."""
        return self.link.wind.value

    # ---- link events -------------------------------------------------------------------------
    def on_telemetry(self, telemetry: Telemetry, now: float) -> None:
        self.link.on_telemetry(telemetry, now)
        self.mission.write_awaited(now)
        news = self.flight.on_telemetry(now)
        if news is FlightNews.REACHED:
            # The fix that proved the arrival goes on the bus (and so into recordings)
            # before the outcome, whatever the telemetry rate: a "reached" can be checked
            # against it. Rate-limited samples are tens of metres apart at a speedup, and
            # the aircraft turns back to its course right after this one.
            self._outputs.publish(self._telemetry_key, telemetry)
        self.mission.on_flight(news, now)
        self.zone_watch.check(self.link.gps, self.flight.zones, self.mission.current(), now)

    def on_track(self, track: Track, now: float) -> None:
        self.mission.on_flight(self.flight.on_track(track, now), now)

    def on_waypoint(self, waypoint: Waypoint, now: float) -> None:
        self.flight.on_waypoint(waypoint, now)

    # ---- ground commands ---------------------------------------------------------------------
    def on_opm(self, command: OpmCommand, now: float) -> None:
        if not math.isfinite(command.status_rate_hz) or command.status_rate_hz < 0:
            text = f"error: OPM status rate {command.status_rate_hz!r} refused"
            self.report.status(StatusKind.OPM_REFUSED, text, now)
            return
        changed = command.enabled != self.flight.enabled
        self.flight.enabled = command.enabled
        self.report.rate_hz = command.status_rate_hz
        if changed and not self.flight.enabled:
            self.flight.commands.cancel_all("module turned off")
        rate = self.report.rate_hz
        self.report.status(
            StatusKind.MODULE_SET,
            f"module {'on' if self.flight.enabled else 'off'}, state every "
            + (f"{1 / rate:.3g} s" if rate else "change"),
            now,
        )

    def command_autopilot(self, command: AutopilotCommand, now: float, on_done: Completion) -> None:
        self.flight.command_autopilot(command, now, on_done)

    # ---- mission events ----------------------------------------------------------------------
    def on_targets(self, targets: MissionTargets, now: float, *, replayed: bool = False) -> None:
        self.mission.on_targets(targets, now, replayed=replayed)

    def on_result(self, result: UavResult, now: float) -> None:
        self.mission.on_result(result, now)

    def on_assignment(self, report: AssignmentReport, now: float) -> None:
        self.mission.on_assignment(report, now)

    def on_outcome(self, outcome: TargetOutcome, now: float) -> None:
        self.mission.on_outcome(outcome, now)

    def on_abort(self, abort: MissionAbort, now: float) -> None:
        self.mission.on_abort(abort, now)

    def on_proposal(self, proposal: PlanProposal, now: float) -> None:
        self.mission.on_proposal(proposal, now)

    def on_alive(self, uav: int, alive: bool, now: float) -> None:
        self.mission.on_alive(uav, alive, now)

    def on_spoke(self, uav: int, now: float) -> None:
        """A message signed by teammate `uav` was heard, live, or its signed state
        answered: in the secure profile, what makes its liveliness token count."""
        self.mission.on_spoke(uav, now)

    def awaits_word(self) -> list[int]:
        """The teammates whose token is present but does not count yet, for lack of a
        signed word of theirs (the secure profile): their state is asked for."""
        team = self.mission.team
        if not team.vouch:
            return []
        return sorted(uav for uav in team.tokens if team.waiting_for_word(uav))

    def start(self, now: float) -> None:
        """The module started: its autopilot link is awaited from now, and it catches up
        with a mission in progress (a late join or a restart)."""
        self.link.started_at = now
        self.catch_up(now)

    def catch_up(self, now: float, *, force: bool = False) -> None:
        self.mission.catch_up.request(now, force=force)

    # ---- time --------------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        if self.mission.catch_up.tick(now) and self.round is not None:
            self.round.resume(now)  # the catch-up asked the team what it missed
        self.flight.commands.tick(now)
        self.mission.release_gone(now)
        self.mission.collect_plan(now)
        self.link.check(now)
        self.mission.check_target(now)
        self.mission.tick(now)
        if self.report.due(now):
            self.publish_state(now)

    # ---- reporting ---------------------------------------------------------------------------
    @property
    def status(self) -> Say:
        """Say a status message (`StateReport.status`)."""
        return self.report.status

    def publish_state(self, now: float) -> None:
        self.report.publish_state(self.state(now), now)

    def overall_phase(self, now: float) -> tuple[Phase, str | None]:
        """The phase the UAV shows: `off` and `link_lost` outrank the mission's phase."""
        at = self.link.telemetry_at
        return overall_phase(
            enabled=self.flight.enabled,
            silent_s=None if at is None else now - at,
            link_lost=self.link.lost(now),
            mission=None if self.round is None else (self.life.phase, self.life.reason),
        )

    def state(self, now: float) -> UavState:
        progress = None
        if self.round is not None:
            progress = MissionProgress(
                mission=self.round.mission,
                phase=self.life.phase,
                targets=len(self.round.current.targets),
                result=self.round.results.get(self.uav_id),
                assignment=self.round.committed,
                route=self.flight.route,
                targets_digest=targets_digest(self.round.targets),
                current_target=self.flight.target,
                reached=dict(self.round.reached_targets),
                leg_s=self.mission.leg_s(self.round.mission, self.flight.target),
            )
        return self.report.state(
            enabled=self.flight.enabled,
            tracked_waypoint=self.flight.tracked_waypoint,
            telemetry=self.link.telemetry,
            progress=progress,
            shown=self.overall_phase(now),
        )

    # ---- what teammates ask for --------------------------------------------------------------
    def mission_targets(self) -> MissionTargets | None:
        return self.round.current if self.round else None

    def own_result(self, mission: int) -> UavResult | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.results.get(self.uav_id)

    def own_standing(self, mission: int, basis: str | None) -> UavResult | None:
        """This UAV's standing for append plan `basis` of `mission` (None: for the one it
        awaits or follows), as it put it: served to a teammate or a ground that asks."""
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.standing_of(self.uav_id, basis)

    def teammate_standing(self, mission: int, uav: int, basis: str) -> UavResult | None:
        """Teammate `uav`'s standing for append plan `basis` of `mission`, as it signed
        it: relayed to whoever asks by name (an ask for a re-plan in changed air is
        believed from its asker's own standing, and the asker may be gone)."""
        if self.round is None or self.round.mission != mission or uav == self.uav_id:
            return None
        return self.round.standing_of(uav, basis)

    def own_assignment(self, mission: int) -> AssignmentReport | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.committed

    def abort_of(self, mission: int) -> MissionAbort | None:
        return self.mission.abort_of(mission)

    def own_outcome(self, mission: int) -> TargetOutcome | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.outcome

    def teammate_outcomes(self, mission: int) -> dict[int, TargetOutcome]:
        """Each teammate's latest outcome as it signed it: relayed to whoever asks by name."""
        return self.mission.heard_outcomes(mission)
