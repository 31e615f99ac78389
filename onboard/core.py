"""The onboard planning module's logic: what to do with each event, and when.

Events arrive here whichever way they came (Zenoh, or the payload port from a ground
station reachable only over the Piccolo radio): one code path handles a command.
What the module does goes out through `Outputs`, which the process wires to the link
adapter and the Zenoh node, and which unit tests replace with a recorder. No I/O here.

Flying to a target (thesis 4.3): write waypoint TARGET_WAYPOINT at the target with
`next` = the waypoint the aircraft was tracking, then track it; when the autopilot
moves on from it, the aircraft is back on its original course by itself.

Every phase is what the module observed (docs/lifecycle.md): `flying` once the
autopilot echoed the track command, `reached` once telemetry put the aircraft within
REACHED_RADIUS_M of the target, `preempted` when the autopilot left the target route
anywhere else, `link_lost` when telemetry stopped for LINK_LOST_S.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Protocol

import msgspec

from fleet.consensus.mission_round import MissionRound
from fleet.geo.mercator import MercatorProjection, distance_m
from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    CommandResult,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    OpmCommand,
    StatusText,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase, Severity
from fleet.mission.targets_file import TargetsFileError, encode_targets
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand, CommandTracker, Completion
from onboard.planner_worker import PlanRequest, PlanResult

log = logging.getLogger(__name__)

#: The waypoint index the module writes a target into (the flight plan keeps the rest).
TARGET_WAYPOINT = 90
#: Results for missions not seen yet are kept, at most this many, for when they start.
MAX_EARLY_RESULTS = 256
#: Within this distance (m) of its target by telemetry, a UAV has reached it: the
#: autopilot's own acceptance radius (60 m in the simulator) plus what the aircraft
#: flies between two telemetry packets at top speed and 5 Hz.
REACHED_RADIUS_M = 75.0
#: With no telemetry for this long (wall seconds), the autopilot link counts as lost.
LINK_LOST_S = 3.0


class Planner(Protocol):
    """The RunMILP / IsMILPRunning contract (thesis 2.8): see onboard.planner_worker."""

    def run(self, request: PlanRequest) -> bool: ...
    def result(self) -> PlanResult | None: ...


class Outputs(Protocol):
    """Where the module's decisions go."""

    def send_autopilot(self, command: AutopilotCommand) -> None: ...
    def publish(self, key: str, message: msgspec.Struct) -> None: ...
    def send_ground(self, message: StatusText | UavResult) -> None: ...
    def fetch_results(self, mission: int) -> None: ...
    def fetch_assignments(self, mission: int) -> None: ...


@dataclass
class OnboardCore:
    uav_id: int
    outputs: Outputs
    planner: Planner
    planning_budget_s: float = 2.0
    enabled: bool = True
    status_rate_hz: float = 1.0
    telemetry: Telemetry | None = None
    tracked_waypoint: int | None = None
    original_waypoint: int | None = None
    round: MissionRound | None = None
    phase: Phase = Phase.IDLE
    reason: str | None = None  #: why the phase is what it is, where that needs saying
    last_status: str | None = None
    alive: set[int] = field(default_factory=set)
    commands: CommandTracker = field(init=False)
    _early_results: list[UavResult] = field(default_factory=list)
    _aborted: set[int] = field(default_factory=set)
    _last_status_at: float = -math.inf
    _telemetry_at: float | None = None
    _link_lost: bool = False
    _target_tracked: bool = False  #: the autopilot echoed the track to the target waypoint

    def __post_init__(self) -> None:
        self.commands = CommandTracker(send=self.outputs.send_autopilot)
        self.alive.add(self.uav_id)

    # ---- link events -------------------------------------------------------------
    def on_telemetry(self, telemetry: Telemetry, now: float) -> None:
        self.telemetry = telemetry
        self._telemetry_at = now
        self.outputs.publish(keys.telemetry(self.uav_id), telemetry)
        if self._link_lost:
            self._link_lost = False
            self.status("autopilot link back: telemetry flowing again", now)
        if self.phase in (Phase.COMMITTED, Phase.FLYING) and self._target_distance() is not None:
            distance = self._target_distance()
            if distance is not None and distance <= REACHED_RADIUS_M:
                self._reached(distance, now)

    def _target_distance(self) -> float | None:
        """Metres from the latest GPS fix to the committed target; None if either is unknown."""
        report = self.round.committed if self.round else None
        gps = self.telemetry.gps if self.telemetry else None
        if report is None or report.target is None or gps is None or self.round is None:
            return None
        target = self.round.targets.targets[report.target]
        return distance_m((gps.lat, gps.lon), (target.lat, target.lon))

    def _reached(self, distance: float, now: float) -> None:
        self.phase = Phase.REACHED
        self.reason = None
        target = self.round.committed.target if self.round and self.round.committed else None
        self.status(f"reached target {target} ({distance:.0f} m from it)", now)

    def link_lost(self, now: float) -> bool:
        """True while no telemetry has arrived for LINK_LOST_S (or none ever did)."""
        return self._telemetry_at is None or now - self._telemetry_at > LINK_LOST_S

    def on_track(self, track: Track, now: float) -> None:
        self.commands.on_echo(track)
        previous, self.tracked_waypoint = self.tracked_waypoint, track.waypoint
        if previous != track.waypoint:
            self.outputs.publish(keys.track(self.uav_id), track)
        if track.waypoint == TARGET_WAYPOINT:
            return
        if self.phase == Phase.FLYING and self._target_tracked and previous == TARGET_WAYPOINT:
            self._left_target_route(track.waypoint, now)
        if self.phase not in (Phase.COMMITTED, Phase.FLYING):
            self.original_waypoint = track.waypoint  # the course to come back to

    def _left_target_route(self, waypoint: int, now: float) -> None:
        """The autopilot stopped tracking the target: arrival if telemetry says so."""
        distance = self._target_distance()
        if distance is not None and distance <= REACHED_RADIUS_M:
            self._reached(distance, now)
            return
        self.phase = Phase.PREEMPTED
        where = "unknown distance" if distance is None else f"{distance:.0f} m"
        self.reason = f"autopilot left the target route for waypoint {waypoint} at {where}"
        self.status(f"warning: target not reached: {self.reason}", now)

    def on_waypoint(self, waypoint: Waypoint) -> None:
        self.commands.on_echo(waypoint)
        self.outputs.publish(keys.waypoint(self.uav_id, waypoint.index), waypoint)

    # ---- ground commands -----------------------------------------------------------
    def on_opm(self, command: OpmCommand, now: float) -> None:
        if not math.isfinite(command.status_rate_hz) or command.status_rate_hz < 0:
            self.status(f"error: OPM status rate {command.status_rate_hz!r} refused", now)
            return
        changed = command.enabled != self.enabled
        self.enabled = command.enabled
        self.status_rate_hz = command.status_rate_hz
        if changed and not self.enabled:
            self.commands.cancel_all("module turned off")
        self.status(
            f"module {'on' if self.enabled else 'off'}, status every "
            + (f"{1 / self.status_rate_hz:.3g} s" if self.status_rate_hz else "change"),
            now,
        )

    def command_autopilot(self, command: AutopilotCommand, now: float, on_done: Completion) -> None:
        """A waypoint or track asked for by the ground; refused while the module is off."""
        if not self.enabled:
            on_done(CommandResult(False, "module is off: it does not write to the autopilot"))
            return
        self.commands.submit(command, now, on_done)

    def on_targets(self, targets: MissionTargets, now: float) -> None:
        if self.uav_id not in targets.team:
            return
        current = self.round.mission if self.round else None
        if current is not None and targets.mission <= current:
            return  # a repeat of the current mission, or a stale one
        if targets.mission in self._aborted:
            return
        problem = self._refusal(targets)
        if problem is not None:
            # Bad input never disturbs the mission in progress.
            self.status(f"error: mission {targets.mission} refused: {problem}", now)
            return
        self._start_round(targets, now)
        # A UAV that joins late or restarts adopts what its teammates committed.
        self.outputs.fetch_assignments(targets.mission)
        if self.telemetry is None or self.telemetry.gps is None:
            self._decline(f"mission {targets.mission}: no GPS telemetry yet", now)
        elif self.link_lost(now):
            self._decline(f"mission {targets.mission}: autopilot link lost", now)
        elif not self.enabled:
            self.status(f"mission {targets.mission}: module off, not taking part", now)
            self._publish_result(tuple(None for _ in targets.targets), now)
        else:
            self._start_planning(now)

    def _decline(self, why: str, now: float) -> None:
        """Take no part in the current mission: an all-None result says so to the team."""
        assert self.round is not None
        self.reason = why
        self.status(f"warning: {why}: not taking part", now)
        self._publish_result(tuple(None for _ in self.round.targets.targets), now)

    def _refusal(self, targets: MissionTargets) -> str | None:
        try:
            encode_targets(targets.targets, source=f"mission {targets.mission}")
        except TargetsFileError as error:
            return f"target {error.index}: {error.problem}" if targets.targets else error.problem
        if not math.isfinite(targets.deadline_s) or targets.deadline_s <= 0:
            return f"deadline {targets.deadline_s!r} s is not a positive number"
        return None

    def _start_round(self, targets: MissionTargets, now: float) -> None:
        # Cancel first: the resume submitted next must survive the new mission's start.
        self.commands.cancel_all(f"mission {targets.mission} started")
        if self.phase in (Phase.COMMITTED, Phase.FLYING):
            self._resume_course(now)
        self.round = MissionRound(targets, self.uav_id, now)
        self.phase = Phase.COMPUTING
        self.reason = None
        self._target_tracked = False
        early, self._early_results = self._early_results, []
        for result in early:
            if result.mission == targets.mission:
                self.round.add_result(result)
            elif result.mission > targets.mission:
                self._early_results.append(result)

    def _start_planning(self, now: float) -> None:
        assert self.round is not None and self.telemetry is not None
        gps = self.telemetry.gps
        assert gps is not None
        projection = MercatorProjection(gps.lat, gps.lon)
        targets = tuple(projection.to_xy(t.lat, t.lon) for t in self.round.targets.targets)
        request = PlanRequest(
            position=(0.0, 0.0),
            velocity=(gps.vel_east, gps.vel_north),
            targets=targets,
            budget_s=self.planning_budget_s,
            cruise_speed=math.hypot(gps.vel_east, gps.vel_north),
        )
        if not self.planner.run(request):
            self.status("warning: planner still busy with the previous mission", now)
            return
        self.status(
            f"mission {self.round.mission}: computing approach times to {len(targets)} targets",
            now,
        )

    def on_result(self, result: UavResult, now: float) -> None:
        if self.round is None or result.mission > self.round.mission:
            self._early_results = [*self._early_results, result][-MAX_EARLY_RESULTS:]
            return
        if result.uav != self.uav_id:
            self.round.add_result(result)

    def on_assignment(self, report: AssignmentReport, now: float) -> None:
        if self.round is None or report.uav == self.uav_id:
            return
        if report.mission != self.round.mission or self.round.committed is not None:
            return
        if report.mission in self._aborted:
            return
        adopted = self.round.adopt(report)
        if adopted is not None:
            self.status(
                f"mission {report.mission}: adopted the assignment of UAV {report.uav}", now
            )
            self._commit(adopted, now)

    def on_abort(self, abort: MissionAbort, now: float) -> None:
        """Abort is final: mission m never commits or flies after this, whatever arrives."""
        if abort.uav is not None and abort.uav != self.uav_id:
            return  # a teammate's own abort: this UAV flies on
        self._aborted.add(abort.mission)
        if self.round is None or self.round.mission != abort.mission:
            return
        if self.phase == Phase.ABORTED:
            return
        self.commands.cancel_all(f"mission {abort.mission} aborted")
        flying = self.phase in (Phase.COMMITTED, Phase.FLYING)
        if flying:
            self._resume_course(now)
        self.phase = Phase.ABORTED
        self.reason = None
        course = "back on course" if flying else "it was not flying a target"
        self.status(f"mission {abort.mission} aborted; {course}", now)

    def on_alive(self, uav: int, alive: bool) -> None:
        if alive:
            self.alive.add(uav)
        elif uav != self.uav_id:
            self.alive.discard(uav)

    # ---- time ----------------------------------------------------------------------
    def tick(self, now: float) -> None:
        self.commands.tick(now)
        self._collect_plan(now)
        self._check_link(now)
        mission_round = self.round
        if (
            mission_round is not None
            and mission_round.committed is None
            and mission_round.mission not in self._aborted
        ):
            if mission_round.should_fetch(now, self.alive):
                mission_round.last_fetch = now
                self.outputs.fetch_results(mission_round.mission)
            if mission_round.ready(now, self.alive):
                missing = mission_round.missing(self.alive)
                report = mission_round.decide(self.alive)
                if missing:
                    self.status(
                        f"mission {mission_round.mission}: deadline passed without "
                        f"{', '.join(map(str, sorted(missing)))}; assigned without them",
                        now,
                    )
                self._commit(report, now)
        if self.status_rate_hz > 0 and now - self._last_status_at >= 1 / self.status_rate_hz:
            self.status(self._summary(), now)

    def _check_link(self, now: float) -> None:
        if self._telemetry_at is None or self._link_lost or not self.link_lost(now):
            return
        self._link_lost = True
        self.status(f"error: autopilot link lost: no telemetry for over {LINK_LOST_S:g} s", now)

    def _collect_plan(self, now: float) -> None:
        result = self.planner.result()
        if result is None or self.round is None or self.phase != Phase.COMPUTING:
            return
        if len(result.times) != len(self.round.targets.targets):
            return  # the answer to a superseded mission
        self._report_plan(result, now)

    def _report_plan(self, plan: PlanResult, now: float) -> None:
        fallbacks = sum(plan.fallback)
        mission = self.round.mission if self.round else "?"
        text = f"mission {mission}: approach times in {plan.solve_seconds:.2f} s"
        if fallbacks:
            text += f"; {fallbacks} by the Dubins fallback (budget {self.planning_budget_s:g} s)"
        if plan.error:
            text = f"warning: {text}; solver error: {plan.error}"
        self.status(text, now)
        self._publish_result(tuple(plan.times), now, plan.model_times, plan.fallback_times)

    def _publish_result(
        self,
        times: tuple[float | None, ...],
        now: float,
        model_times: int | None = None,
        fallback_times: int | None = None,
    ) -> None:
        assert self.round is not None
        result = UavResult(
            mission=self.round.mission,
            uav=self.uav_id,
            times=times,
            model_times=model_times,
            fallback_times=fallback_times,
        )
        self.round.add_result(result)
        # Teammates are computing too: the first fetch waits one interval.
        self.round.last_fetch = now
        if self.round.committed is None and self.phase == Phase.COMPUTING:
            self.phase = Phase.WAITING
        self.outputs.publish(keys.mission_result(result.mission, self.uav_id), result)
        self.outputs.send_ground(result)

    def _commit(self, report: AssignmentReport, now: float) -> None:
        self.outputs.publish(keys.mission_assignment(report.mission, self.uav_id), report)
        if report.target is None:
            self.phase = Phase.IDLE
            self.status(f"mission {report.mission}: no target assigned; keeping course", now)
            return
        assert self.round is not None
        target = self.round.targets.targets[report.target]
        eta = f"{report.eta_s:.0f} s" if report.eta_s is not None else "unknown"
        self.status(f"mission {report.mission}: target {report.target} chosen, ETA {eta}", now)
        self.phase = Phase.COMMITTED
        if not self.enabled:
            return
        # on_track never records the target waypoint as the course; 0 before any track.
        back_to = 0 if self.original_waypoint is None else self.original_waypoint
        waypoint = Waypoint(
            index=TARGET_WAYPOINT,
            next_index=back_to,
            lat=target.lat,
            lon=target.lon,
            alt=target.alt,
        )
        mission = report.mission

        def track_target(result: CommandResult) -> None:
            if self._superseded(mission):
                return
            if not result.ok:
                self._failed(f"target waypoint not stored: {result.detail}", now)
                return
            self.commands.submit(Track(TARGET_WAYPOINT), now, tracked)

        def tracked(result: CommandResult) -> None:
            if self._superseded(mission):
                return
            if not result.ok:
                self._failed(f"track to the target not confirmed: {result.detail}", now)
                return
            self._target_tracked = True
            if self.phase == Phase.COMMITTED:
                self.phase = Phase.FLYING
                self.status(f"mission {mission}: flying to target {report.target}", now)

        self.commands.submit(waypoint, now, track_target)

    def _superseded(self, mission: int) -> bool:
        """A command's answer arrived after its mission was replaced or aborted."""
        return self.round is None or self.round.mission != mission or mission in self._aborted

    def _failed(self, why: str, now: float) -> None:
        self.phase = Phase.FAILED
        self.reason = why
        mission = self.round.mission if self.round else "?"
        self.status(f"error: mission {mission}: cannot fly the target: {why}", now)

    def _resume_course(self, now: float) -> None:
        if self.original_waypoint is None or not self.enabled:
            return
        back = self.original_waypoint

        def done(result: CommandResult) -> None:
            if not result.ok:
                self.status(f"error: could not resume waypoint {back}: {result.detail}", now)

        self.commands.submit(Track(back), now, done)

    # ---- reporting -----------------------------------------------------------------
    def status(self, text: str, now: float) -> None:
        self._last_status_at = now
        self.last_status = text
        severity = Severity.of_text(text)
        (log.info if severity == Severity.INFO else log.warning)("%s", text)
        message = StatusText(text, severity)
        self.outputs.publish(keys.status(self.uav_id), message)
        self.outputs.send_ground(message)

    def _summary(self) -> str:
        parts = [f"module {'on' if self.enabled else 'off'}"]
        if self.tracked_waypoint is not None:
            parts.append(f"tracking waypoint {self.tracked_waypoint}")
        if self.round is not None:
            parts.append(f"mission {self.round.mission} {self.phase}")
            report = self.round.committed
            if report is not None and report.target is not None:
                parts.append(f"target {report.target}")
        return "; ".join(parts)

    def overall_phase(self, now: float) -> tuple[Phase, str | None]:
        """The phase the UAV shows: `off` and `link_lost` outrank the mission's phase."""
        if not self.enabled:
            return Phase.OFF, "the onboard planning module is turned off"
        if self._telemetry_at is not None and self.link_lost(now):
            age = now - self._telemetry_at
            return Phase.LINK_LOST, f"no telemetry from the autopilot for {age:.1f} s"
        if self.round is None:
            return Phase.IDLE, None
        return self.phase, self.reason

    def state(self, now: float) -> UavState:
        progress = None
        if self.round is not None:
            progress = MissionProgress(
                mission=self.round.mission,
                phase=self.phase,
                targets=len(self.round.targets.targets),
                result=self.round.results.get(self.uav_id),
                assignment=self.round.committed,
            )
        phase, reason = self.overall_phase(now)
        return UavState(
            uav=self.uav_id,
            enabled=self.enabled,
            status_rate_hz=self.status_rate_hz,
            tracked_waypoint=self.tracked_waypoint,
            telemetry=self.telemetry,
            link=None,
            mission=progress,
            last_status=self.last_status,
            phase=phase,
            reason=reason,
        )

    def mission_targets(self) -> MissionTargets | None:
        return self.round.targets if self.round else None

    def own_result(self, mission: int) -> UavResult | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.results.get(self.uav_id)

    def own_assignment(self, mission: int) -> AssignmentReport | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.committed
