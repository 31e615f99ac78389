"""The onboard planning module's logic: what to do with each event, and when.

Events arrive here whichever way they came (Zenoh, or the payload port from a ground
station reachable only over the Piccolo radio): one code path handles a command.
What the module does goes out through `Outputs`, which the process wires to the link
adapter and the bus edge, and which unit tests replace with a recorder. No I/O here.

Flying to a target (thesis 4.3): write waypoint TARGET_WAYPOINT at the target with
`next` = the waypoint the aircraft was tracking, then track it; when the autopilot
moves on from it, the aircraft is back on its original course by itself.

Every phase is what the module observed (docs/lifecycle.md), moved by the one table in
`fleet.mission.lifecycle`: `flying` once the autopilot echoed the track command,
`reached` once telemetry put the aircraft within REACHED_RADIUS_M of the target,
`preempted` when the autopilot left the target route anywhere else or the ground
commanded it directly, `link_lost` when telemetry stopped for LINK_LOST_S, `failed`
when the target could not be flown (then the UAV is released and its teammates re-plan
its target: fleet.consensus.replan).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Protocol

import msgspec

from fleet.consensus.mission_round import MissionRound, Settled, assignment_problem
from fleet.geo.mercator import MercatorProjection, distance_m
from fleet.mission import keys
from fleet.mission.lifecycle import Observation, advance, holds_target
from fleet.mission.messages import (
    AssignmentReport,
    CommandResult,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    OpmCommand,
    StatusText,
    TargetOutcome,
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
#: A target not confirmed by the autopilot this long after the commitment (the writes
#: are retried all along, across link outages) is given up: `failed`, and released.
CONFIRM_LIMIT_S = 20.0
#: A UAV holding a target whose autopilot link stays lost this long is released.
LINK_RELEASE_S = 20.0
#: A committed teammate whose liveliness token stays gone this long (s) is released. A
#: router failover withdraws every token learned through the dead router and declares
#: it again through the surviving path some milliseconds later: releasing at once
#: re-planned both UAVs of a two-router mesh apart, each without the other.
LIVELINESS_GRACE_S = 2.0
#: The share of a mission's deadline the approach model may use (see `_budget`).
PLAN_SHARE_OF_DEADLINE = 0.5
#: At most one catch-up query (live missions, the teammates' assignments) this often.
CATCH_UP_INTERVAL_S = 5.0
#: Two ticks this far apart (s; the main loop ticks every 0.25 s) mean the module itself
#: was suspended (SIGSTOP, a starved machine): it catches up at once, and again after
#: each of these delays (s), for its bus session may still be working off the backlog
#: or reconnecting, and a query then goes unanswered.
SUSPENDED_S = 2.0
CATCH_UP_AFTER_SUSPENSION_S = (1.0, 3.0)


class Planner(Protocol):
    """The RunMILP / IsMILPRunning contract (thesis 2.8): see onboard.planner_worker."""

    def run(self, request: PlanRequest) -> bool: ...
    def result(self) -> PlanResult | None: ...


class Outputs(Protocol):
    """Where the module's decisions go."""

    def send_autopilot(self, command: AutopilotCommand) -> None: ...
    def publish(self, key: str, message: msgspec.Struct) -> None: ...
    def send_ground(self, message: StatusText | UavResult) -> None: ...
    def fetch_results(self, mission: int, uavs: tuple[int, ...]) -> None: ...
    def fetch_assignments(self, mission: int) -> None: ...
    def fetch_missions(self) -> None: ...


@dataclass
class OnboardCore:
    uav_id: int
    outputs: Outputs
    planner: Planner
    planning_budget_s: float = 2.0
    enabled: bool = True
    #: How often the UAV's state is published on its state key (0: only on query).
    status_rate_hz: float = 1.0
    #: A target not echoed this long after the commitment is given up (CONFIRM_LIMIT_S).
    confirm_limit_s: float = CONFIRM_LIMIT_S
    #: A held target whose autopilot link stays lost this long is released (LINK_RELEASE_S).
    link_release_s: float = LINK_RELEASE_S
    #: A committed teammate gone from liveliness this long is released (LIVELINESS_GRACE_S).
    liveliness_grace_s: float = LIVELINESS_GRACE_S
    telemetry: Telemetry | None = None
    tracked_waypoint: int | None = None
    original_waypoint: int | None = None
    round: MissionRound | None = None
    phase: Phase = Phase.IDLE
    reason: str | None = None  #: why the phase is what it is, where that needs saying
    last_status: str | None = None
    alive: set[int] = field(default_factory=set)
    #: A snapshot of what this UAV settled of its mission (`Settled`), replaced as it
    #: changes: the bus threads drop the assignment reports it covers by their header.
    settled: Settled | None = None
    commands: CommandTracker = field(init=False)
    _early_results: list[UavResult] = field(default_factory=list)
    _aborted: set[int] = field(default_factory=set)
    _abort: MissionAbort | None = None  #: the abort this UAV obeyed last (relayed by query)
    _last_state_at: float = -math.inf
    _telemetry_at: float | None = None
    _link_lost: bool = False
    _request: PlanRequest | None = None  #: the plan asked for the current mission
    _target: int | None = None  #: the target this UAV holds (committed or flying to)
    _committed_at: float = 0.0
    _caught_up_at: float = -math.inf
    _ticked_at: float | None = None
    _resumed_at: float = -math.inf  #: when a suspension of this module was last noticed
    _catch_ups_due: list[float] = field(default_factory=list)
    _gone_since: dict[int, float] = field(default_factory=dict)  #: liveliness lost, when
    _target_tracked: bool = False  #: the autopilot echoed the track to the target waypoint
    _resuming: bool = False  #: a resume of the course is sent and not echoed yet
    _operator_track: bool = False  #: the ground commanded the target waypoint or its track

    def __post_init__(self) -> None:
        self.commands = CommandTracker(send=self.outputs.send_autopilot)
        self.alive.add(self.uav_id)

    # ---- the life cycle ----------------------------------------------------------------
    def _observe(self, observation: Observation, reason: str | None = None) -> bool:
        """Move the phase by the life-cycle table; True if it changed."""
        after = advance(self.phase, observation)
        if after == self.phase:
            return False
        self.phase = after
        self.reason = reason
        return True

    # ---- link events -------------------------------------------------------------
    def on_telemetry(self, telemetry: Telemetry, now: float) -> None:
        self.telemetry = telemetry
        self._telemetry_at = now
        if self._link_lost:
            self._link_lost = False
            self.status("autopilot link back: telemetry flowing again", now)
        if holds_target(self.phase):
            distance = self._target_distance()
            if distance is not None and distance <= REACHED_RADIUS_M:
                self._reached(distance, now)

    def _target_distance(self) -> float | None:
        """Metres from the latest GPS fix to the held target; None if either is unknown."""
        gps = self.telemetry.gps if self.telemetry else None
        if self._target is None or gps is None or self.round is None:
            return None
        target = self.round.targets.targets[self._target]
        return distance_m((gps.lat, gps.lon), (target.lat, target.lon))

    def _reached(self, distance: float, now: float) -> None:
        # Reached before the track was echoed (it passed by): the target writes still
        # pending would only turn it back to where it has been.
        self.commands.cancel_where(_is_target_write, f"target {self._target} reached")
        self._observe(Observation.WITHIN_RADIUS)
        self.status(f"reached target {self._target} ({distance:.0f} m from it)", now)
        self._publish_outcome(Phase.REACHED, None)

    def link_lost(self, now: float) -> bool:
        """True while no telemetry has arrived for LINK_LOST_S (or none ever did)."""
        return self._telemetry_at is None or now - self._telemetry_at > LINK_LOST_S

    def on_track(self, track: Track, now: float) -> None:
        self.commands.on_echo(track, now)
        previous, self.tracked_waypoint = self.tracked_waypoint, track.waypoint
        if previous != track.waypoint:
            self.outputs.publish(keys.track(self.uav_id), track)
        if track.waypoint == TARGET_WAYPOINT:
            if previous != TARGET_WAYPOINT and self._target is None:
                self._leave_stale_target(now)  # a restart's first track, after the re-plan
            return
        if self.phase == Phase.FLYING and self._target_tracked and previous == TARGET_WAYPOINT:
            self._left_target_route(track.waypoint, now)
        if not holds_target(self.phase):
            self.original_waypoint = track.waypoint  # the course to come back to

    def _left_target_route(self, waypoint: int, now: float) -> None:
        """The autopilot stopped tracking the target: arrival if telemetry says so."""
        distance = self._target_distance()
        if distance is not None and distance <= REACHED_RADIUS_M:
            self._reached(distance, now)
            return
        where = "unknown distance" if distance is None else f"{distance:.0f} m"
        why = f"autopilot left the target route for waypoint {waypoint} at {where}"
        self._observe(Observation.LEFT_ROUTE, why)
        self.status(f"warning: target not reached: {why}", now)

    def on_waypoint(self, waypoint: Waypoint, now: float) -> None:
        self.commands.on_echo(waypoint, now)
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
            f"module {'on' if self.enabled else 'off'}, state every "
            + (f"{1 / self.status_rate_hz:.3g} s" if self.status_rate_hz else "change"),
            now,
        )

    def command_autopilot(self, command: AutopilotCommand, now: float, on_done: Completion) -> None:
        """A waypoint or track asked for by the ground; refused while the module is off.

        Commanding the track, or the target waypoint, while holding a target takes the
        aircraft off it: the mission's part is `preempted` at once, with that reason.
        """
        if not self.enabled:
            on_done(CommandResult(False, "module is off: it does not write to the autopilot"))
            return
        retasks = isinstance(command, Track) or command.index == TARGET_WAYPOINT
        self._operator_track = isinstance(command, Track) and command.waypoint == TARGET_WAYPOINT
        if retasks and holds_target(self.phase):
            what = (
                f"track to waypoint {command.waypoint}"
                if isinstance(command, Track)
                else f"waypoint {command.index}"
            )
            why = f"the ground commanded the autopilot directly ({what})"
            self.commands.cancel_all(why)
            self._observe(Observation.OPERATOR_COMMAND, why)
            self.status(f"warning: target {self._target} given up: {why}", now)
        self.commands.submit(command, now, on_done)

    def on_targets(self, targets: MissionTargets, now: float, *, replayed: bool = False) -> None:
        """A mission's targets, heard live or (`replayed`) in reply to a catch-up."""
        if self.uav_id not in targets.team:
            return
        current = self.round.mission if self.round else None
        if current is not None and targets.mission <= current:
            return  # a repeat of the current mission, or a stale one
        if targets.mission in self._aborted:
            # Its abort came first (this UAV was away when the mission was sent): the
            # mission still replaces the old one, as on every teammate, and shows aborted.
            self._start_round(targets, now)
            self._observe(Observation.ABORTED)
            self.status(f"mission {targets.mission} arrived already aborted: not flying it", now)
            return
        problem = self._refusal(targets)
        if problem is not None:
            # Bad input never disturbs the mission in progress.
            self.status(f"error: mission {targets.mission} refused: {problem}", now)
            return
        # Heard just after this module was suspended, a mission may have been sent
        # while it was: its teammates may have decided on it already.
        late = replayed or self._resumed(now)
        self._start_round(targets, now, late=late)
        if late:
            # Learnt from a catch-up (a late join, a restart) or after a freeze: the
            # team may have decided on it already, and this UAV adopts that. A mission
            # heard live is as new to the team as to this UAV: asking would cost every
            # teammate three queries while they all plan.
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
        self.status(f"warning: {why}: not taking part", now)
        self._publish_result(tuple(None for _ in self.round.targets.targets), now)
        self.reason = why

    def _refusal(self, targets: MissionTargets) -> str | None:
        try:
            encode_targets(targets.targets, source=f"mission {targets.mission}")
        except TargetsFileError as error:
            return f"target {error.index}: {error.problem}" if targets.targets else error.problem
        if not math.isfinite(targets.deadline_s) or targets.deadline_s <= 0:
            return f"deadline {targets.deadline_s!r} s is not a positive number"
        return None

    def _start_round(self, targets: MissionTargets, now: float, *, late: bool = False) -> None:
        """Replace the mission in one step: nothing of the old one survives it."""
        # Cancel first: the resume submitted next must survive the new mission's start.
        resuming = self._resuming
        self.commands.cancel_all(f"mission {targets.mission} started")
        if holds_target(self.phase) or resuming:
            self._resume_course(now)
        self.round = MissionRound(targets, self.uav_id, now, late=late)
        self._observe(Observation.MISSION_STARTED)
        self._request = None
        self._target = None
        self._target_tracked = False
        early, self._early_results = self._early_results, []
        for result in early:
            if result.mission == targets.mission:
                self.round.add_result(result)
            elif result.mission > targets.mission:
                self._early_results.append(result)
        self._settle()

    def _settle(self) -> None:
        """Publish a new snapshot of what this UAV settled (after any change to it)."""
        mission_round = self.round
        if mission_round is not None:
            self.settled = mission_round.settled(mission_round.mission in self._aborted)

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
            budget_s=self._budget(self.round.targets),
            cruise_speed=math.hypot(gps.vel_east, gps.vel_north),
        )
        # The planner drops a run still under way for an older mission: its answer would
        # be that mission's approach times.
        if not self.planner.run(request):
            self._decline(f"mission {self.round.mission}: the planner refused the request", now)
            return
        self._request = request
        self.status(
            f"mission {self.round.mission}: computing approach times to {len(targets)} targets",
            now,
        )

    def _budget(self, targets: MissionTargets) -> float:
        """The planning budget for this mission: the module's own, or half the mission's
        deadline if that is longer. The other half is for the exchange of results: the
        ground lengthens the deadline for a large team (fleet.consensus.deadline), and
        the approach model gets that time too, instead of answering by the fallback."""
        return max(self.planning_budget_s, PLAN_SHARE_OF_DEADLINE * targets.deadline_s)

    def on_result(self, result: UavResult, now: float) -> None:
        mission_round = self.round
        if mission_round is None or result.mission > mission_round.mission:
            self._early_results = [*self._early_results, result][-MAX_EARLY_RESULTS:]
            return
        if result.uav == self.uav_id or not mission_round.add_result(result):
            return
        mission_round.heard(now)
        if mission_round.committed is not None and mission_round.released:
            self._replan(now)  # it may have waited for this result

    def on_assignment(self, report: AssignmentReport, now: float) -> None:
        mission_round = self.round
        if mission_round is None or report.uav == self.uav_id:
            return
        if report.mission != mission_round.mission or report.mission in self._aborted:
            return
        problem = assignment_problem(report, mission_round.targets)
        if problem is not None:
            log.warning(
                "mission %d: UAV %d's assignment refused: %s",
                *(report.mission, report.uav),
                problem,
            )
            return
        if mission_round.committed is None:
            self._adopt(report, now)
        elif mission_round.release(report.released):
            self._replan(now)
        elif (followed := mission_round.follow(report)) is not None:
            self._apply(followed, now)
        self._settle()

    def _adopt(self, report: AssignmentReport, now: float) -> None:
        assert self.round is not None
        adopted = self.round.adopt(report, self.alive, now)
        if adopted is None:
            unused = sorted(self.round.thinner(report, self.alive, now))
            log.info(
                "mission %d: UAV %d's assignment not adopted: it was computed without the "
                "results of %s, which this UAV holds",
                report.mission,
                report.uav,
                ", ".join(map(str, unused)),
            )
            return
        self.status(f"mission {report.mission}: adopted the assignment of UAV {report.uav}", now)
        self._apply(adopted, now)
        self._replan_if_released(now)

    def on_outcome(self, outcome: TargetOutcome, now: float) -> None:
        """A teammate reached its target, or dropped out of the mission (failed, link lost)."""
        mission_round = self.round
        if mission_round is None or outcome.uav == self.uav_id:
            return
        if outcome.mission != mission_round.mission:
            return
        if outcome.phase == Phase.REACHED:
            mission_round.reached.add(outcome.uav)
            self._settle()
            return
        dropped = outcome.phase in (Phase.FAILED, Phase.LINK_LOST)
        if dropped and mission_round.release((outcome.uav,)):
            self.status(
                f"mission {outcome.mission}: UAV {outcome.uav} dropped out "
                f"({outcome.reason or outcome.phase}); re-planning its target",
                now,
            )
            self._replan(now)
            self._settle()

    def on_abort(self, abort: MissionAbort, now: float) -> None:
        """Abort is final: mission m never commits or flies after this, whatever arrives."""
        if abort.uav is not None and abort.uav != self.uav_id:
            return  # a teammate's own abort: this UAV flies on
        self._aborted.add(abort.mission)
        self._abort = abort
        if self.round is None or self.round.mission != abort.mission:
            return
        self._settle()
        if self.phase == Phase.ABORTED:
            return
        resuming = self._resuming  # a resume still pending (a link outage) goes on
        self.commands.cancel_all(f"mission {abort.mission} aborted")
        flying = holds_target(self.phase)
        if flying or resuming:
            self._resume_course(now)
        self._observe(Observation.ABORTED)
        course = "back on course" if flying else "it was not flying a target"
        self.status(f"mission {abort.mission} aborted; {course}", now)

    def on_alive(self, uav: int, alive: bool, now: float) -> None:
        if alive:
            if uav not in self.alive:
                self.catch_up(now)
            self.alive.add(uav)
            self._gone_since.pop(uav, None)
            return
        if uav == self.uav_id:
            return
        # Before the commitment the consensus leaves it out at once; after, it is
        # released only if it stays gone (LIVELINESS_GRACE_S).
        self.alive.discard(uav)
        if self.round is not None and self.round.committed is not None:
            self._gone_since.setdefault(uav, now)
            self._release_gone(now)  # at once when there is no grace

    def _release_gone(self, now: float) -> None:
        """Release the committed teammates whose liveliness stayed gone past the grace."""
        for uav, since in list(self._gone_since.items()):
            if now - since >= self.liveliness_grace_s:
                del self._gone_since[uav]
                self._release_lost(uav, now)

    def _release_lost(self, uav: int, now: float) -> None:
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return  # before the commitment, the consensus itself leaves it out
        if mission_round.mission in self._aborted:
            return
        if mission_round.release((uav,)):
            self.status(
                f"mission {mission_round.mission}: UAV {uav} lost (liveliness gone); "
                "re-planning its target",
                now,
            )
            self._replan(now)
            self._settle()

    def catch_up(self, now: float, *, force: bool = False) -> None:
        """Ask for the live missions and the current one's assignments: at start, when
        a teammate (re)appears, for this UAV may be the one that was away (frozen, cut
        off), and (`force`) when its own clock shows it was suspended. Brings it in line
        with what was decided meanwhile; else at most once every CATCH_UP_INTERVAL_S."""
        if not force and now - self._caught_up_at < CATCH_UP_INTERVAL_S:
            # Deferred, not dropped: a teammate reappearing just after a catch-up may
            # mean this UAV's own session has only now reconnected, and that catch-up's
            # queries went nowhere.
            due = self._caught_up_at + CATCH_UP_INTERVAL_S
            if due not in self._catch_ups_due:
                self._catch_ups_due = sorted([*self._catch_ups_due, due])
            return
        self._caught_up_at = now
        self.outputs.fetch_missions()
        if self.round is not None:
            self.outputs.fetch_assignments(self.round.mission)

    # ---- time ----------------------------------------------------------------------
    def _ticks_missed(self, now: float) -> bool:
        """The main loop has not ticked for SUSPENDED_S: the module was suspended."""
        return self._ticked_at is not None and now - self._ticked_at > SUSPENDED_S

    def _resumed(self, now: float) -> bool:
        """Whether this module was suspended just before `now`: ticks missed (an event
        may be handled before the first tick after it), or the tick noticed it within
        the last catch-ups' span."""
        return self._ticks_missed(now) or now - self._resumed_at <= CATCH_UP_AFTER_SUSPENSION_S[-1]

    def tick(self, now: float) -> None:
        if self._ticks_missed(now):
            assert self._ticked_at is not None
            self._resumed_at = now
            # Frozen shorter than Zenoh's lease, no teammate seemed to come back, and
            # what was published meanwhile may be lost: ask for it.
            log.info("no tick for %.1f s: catching up", now - self._ticked_at)
            self.catch_up(now, force=True)
            self._catch_ups_due = [now + delay for delay in CATCH_UP_AFTER_SUSPENSION_S]
        elif self._catch_ups_due and now >= self._catch_ups_due[0]:
            self._catch_ups_due.pop(0)
            self.catch_up(now, force=True)
        self._ticked_at = now
        self.commands.tick(now)
        self._release_gone(now)
        self._collect_plan(now)
        self._check_link(now)
        self._check_target(now)
        mission_round = self.round
        if (
            mission_round is not None
            and mission_round.committed is None
            and mission_round.mission not in self._aborted
        ):
            if mission_round.should_fetch(now, self.alive):
                mission_round.last_fetch = now
                missing = mission_round.missing(self.alive) - {self.uav_id}
                self.outputs.fetch_results(mission_round.mission, tuple(sorted(missing)))
            if mission_round.ready(now, self.alive):
                self._decide_or_ask(mission_round, now)
        if self.status_rate_hz > 0 and now - self._last_state_at >= 1 / self.status_rate_hz:
            self.publish_state(now)

    def publish_state(self, now: float) -> None:
        """The UAV's state on its state key: the periodic report, kept out of the status box."""
        self._last_state_at = now
        self.outputs.publish(keys.state(self.uav_id), self.state(now))

    def _decide_or_ask(self, mission_round: MissionRound, now: float) -> None:
        """Decide, unless the decision might not be the team's: then ask the team what
        it decided first, and decide ASK_GRACE_S later if no answer was adopted (or at
        once, if what made it uncertain is gone: a missing result arrived)."""
        if not mission_round.must_ask(self.alive):
            self._decide(mission_round, now)
        elif mission_round.asked_at is None:
            mission_round.asked_at = now
            excluded = sorted(mission_round.excluded(self.alive))
            log.info(
                "mission %d: asking the team what it decided before deciding (%s)",
                mission_round.mission,
                f"without {', '.join(map(str, excluded))}" if excluded else "the mission came late",
            )
            self.outputs.fetch_assignments(mission_round.mission)
        elif not mission_round.asking(now):
            self._decide(mission_round, now)

    def _decide(self, mission_round: MissionRound, now: float) -> None:
        missing = mission_round.missing(self.alive)
        report = mission_round.decide(self.alive)
        if missing:
            self.status(
                f"warning: mission {mission_round.mission}: deadline passed without "
                f"{', '.join(map(str, sorted(missing)))}; assigned without them",
                now,
            )
        self._apply(report, now)
        self._replan_if_released(now)

    def _check_link(self, now: float) -> None:
        if self._telemetry_at is None or self._link_lost or not self.link_lost(now):
            return
        self._link_lost = True
        self.status(f"error: autopilot link lost: no telemetry for over {LINK_LOST_S:g} s", now)

    def _check_target(self, now: float) -> None:
        """Give up a target the autopilot cannot be made to fly: it is re-planned."""
        if not holds_target(self.phase) or self._telemetry_at is None:
            return
        silent = now - self._telemetry_at
        if silent > self.link_release_s:
            self._failed(f"autopilot link lost for {silent:.0f} s", now, Phase.LINK_LOST)
        elif self.phase == Phase.COMMITTED and now - self._committed_at > self.confirm_limit_s:
            attempts = "over a lost link" if self.link_lost(now) else "with the link up"
            self._failed(
                f"target writes not echoed by the autopilot within {self.confirm_limit_s:g} s "
                f"(retried {attempts})",
                now,
            )

    def _collect_plan(self, now: float) -> None:
        result = self.planner.result()
        if result is None or self.round is None or self.phase != Phase.COMPUTING:
            return
        if result.request is not self._request:
            return  # the answer to a superseded mission: never used for this one
        self._report_plan(result, now)

    def _report_plan(self, plan: PlanResult, now: float) -> None:
        fallbacks = sum(plan.fallback)
        mission = self.round.mission if self.round else "?"
        text = f"mission {mission}: approach times in {plan.solve_seconds:.2f} s"
        text += f" ({plan.cpu_seconds:.3f} s of CPU)"
        if fallbacks:
            budget = plan.request.budget_s
            text += f"; {fallbacks} by the Dubins fallback (budget {budget:g} s)"
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
        self._observe(Observation.RESULT_PUBLISHED)
        self.outputs.publish(keys.mission_result(result.mission, self.uav_id), result)
        self.outputs.send_ground(result)

    # ---- the assignment ----------------------------------------------------------------
    def _replan_if_released(self, now: float) -> None:
        """Teammates released before this UAV committed: re-plan at once."""
        mission_round = self.round
        if mission_round is None or mission_round.base is None:
            return
        if mission_round.released & set(mission_round.base.team):
            self._replan(now)

    def _replan(self, now: float) -> None:
        """Re-assign the targets of released UAVs, or fetch the results that needs."""
        mission_round = self.round
        if mission_round is None or mission_round.mission in self._aborted:
            return
        if self.phase == Phase.ABORTED:
            return
        missing = mission_round.replan_missing()
        if missing:
            self.outputs.fetch_results(mission_round.mission, missing)
            return
        report = mission_round.replan()
        if report is None:
            return
        self.status(
            f"mission {report.mission}: re-plan epoch {report.epoch} without "
            f"{', '.join(map(str, report.released))}",
            now,
        )
        self._apply(report, now)

    def _apply(self, report: AssignmentReport, now: float) -> None:
        """Publish the assignment this UAV follows now and fly what it says."""
        self._settle()
        self.outputs.publish(keys.mission_assignment(report.mission, self.uav_id), report)
        if report.epoch > 0:
            # Teammates hear re-plans on a key of their own: the N - 1 epoch-0
            # commitments each UAV would otherwise hear change nothing once it committed
            # (docs/lifecycle.md, "Who hears which assignment").
            self.outputs.publish(keys.mission_replan(report.mission, self.uav_id), report)
        if report.target == self._target:
            if report.target is None and self.phase in (Phase.COMPUTING, Phase.WAITING):
                self._observe(Observation.ASSIGNED_NONE)
                self.status(f"mission {report.mission}: no target assigned; keeping course", now)
            if report.target is None:
                self._leave_stale_target(now)
            return
        if self._target is not None and holds_target(self.phase):
            # Released, or handed another orphan by a later epoch: off the old target.
            self.commands.cancel_all(f"mission {report.mission} epoch {report.epoch}")
            self._resume_course(now)
            self._observe(Observation.RELEASED, f"re-planned at epoch {report.epoch}")
        if report.target is None or self.uav_id in report.released:
            self._target = None
            self._observe(Observation.ASSIGNED_NONE)
            self._leave_stale_target(now)
            return
        self._commit(report, report.target, now)

    def _leave_stale_target(self, now: float) -> None:
        """Holding no target, yet the autopilot tracks the target waypoint: left there by
        this module before a restart, and the target is another UAV's now (a re-plan
        released this one while it was away). Back to the course, or it flies it too."""
        if self.tracked_waypoint != TARGET_WAYPOINT or self._resuming or self._operator_track:
            return
        mission_round = self.round
        if mission_round is None or mission_round.committed is None:
            return  # nothing decided yet: it may still be handed that very target
        self.status(
            "warning: the autopilot still tracks the target waypoint of a target this UAV "
            "no longer holds; resuming the course",
            now,
        )
        self._resume_course(now)

    def _commit(self, report: AssignmentReport, target_index: int, now: float) -> None:
        assert self.round is not None
        if advance(self.phase, Observation.ASSIGNED_TARGET) != Phase.COMMITTED:
            self._refuse_orphan(report, target_index, now)
            return
        self._target = target_index
        self._committed_at = now
        self._target_tracked = False
        eta = f"{report.eta_s:.0f} s" if report.eta_s is not None else "unknown"
        self.status(f"mission {report.mission}: target {target_index} chosen, ETA {eta}", now)
        self._observe(Observation.ASSIGNED_TARGET)
        if not self.enabled:
            return
        if self.link_lost(now) and report.epoch > 0:
            self._failed("handed an orphaned target while its autopilot link is lost", now)
            return
        self._write_target(report.mission, target_index, now)

    def _refuse_orphan(self, report: AssignmentReport, target_index: int, now: float) -> None:
        """A re-plan handed an orphan to a UAV whose part is over (the operator took it
        off its target, or it failed): it does not fly it, and drops out like a failed
        UAV, so that the next epoch hands the orphan on instead of leaving it unflown."""
        why = f"handed target {target_index} at epoch {report.epoch} while {self.phase}"
        self.status(f"warning: mission {report.mission}: {why}: not flying it", now)
        if self.round is None:
            return
        outcome = TargetOutcome(report.mission, self.uav_id, target_index, Phase.FAILED, why)
        self.round.outcome = outcome
        self.outputs.publish(keys.mission_outcome(report.mission, self.uav_id), outcome)
        if self.round.release((self.uav_id,)):
            self._replan(now)

    def _write_target(self, mission: int, target_index: int, now: float) -> None:
        """Write the target waypoint, then track it; both retried until echoed."""
        assert self.round is not None
        self._operator_track = False  # the module's own target route from now on
        target = self.round.targets.targets[target_index]
        # on_track never records the target waypoint as the course; 0 before any track.
        back_to = 0 if self.original_waypoint is None else self.original_waypoint
        waypoint = Waypoint(
            index=TARGET_WAYPOINT,
            next_index=back_to,
            lat=target.lat,
            lon=target.lon,
            alt=target.alt,
        )

        def track_target(result: CommandResult) -> None:
            if result.ok and self._still_committed(mission, target_index):
                self.commands.submit(Track(TARGET_WAYPOINT), now, tracked, persistent=True)

        def tracked(result: CommandResult) -> None:
            if not result.ok or self._superseded(mission) or self._target != target_index:
                return
            self._target_tracked = True
            if self._observe(Observation.TRACK_ECHOED):
                self.status(f"mission {mission}: flying to target {target_index}", now)

        self.commands.submit(waypoint, now, track_target, persistent=True)

    def _still_committed(self, mission: int, target_index: int) -> bool:
        return (
            not self._superseded(mission)
            and self._target == target_index
            and self.phase == Phase.COMMITTED
        )

    def _superseded(self, mission: int) -> bool:
        """A command's answer arrived after its mission was replaced or aborted."""
        return self.round is None or self.round.mission != mission or mission in self._aborted

    def _failed(self, why: str, now: float, cause: Phase = Phase.FAILED) -> None:
        """This UAV cannot fly its target: say so, resume course, and release the target."""
        self.commands.cancel_all(why)
        self._resume_course(now)
        lost = cause == Phase.LINK_LOST
        self._observe(Observation.LINK_LOST if lost else Observation.COMMAND_FAILED, why)
        mission = self.round.mission if self.round else "?"
        self.status(f"error: mission {mission}: cannot fly target {self._target}: {why}", now)
        self._publish_outcome(cause, why)
        if self.round is not None and self.round.release((self.uav_id,)):
            self._replan(now)

    def _publish_outcome(self, phase: Phase, reason: str | None) -> None:
        if self.round is None:
            return
        outcome = TargetOutcome(
            mission=self.round.mission,
            uav=self.uav_id,
            target=self._target,
            phase=phase,
            reason=reason,
        )
        self.round.outcome = outcome
        self.outputs.publish(keys.mission_outcome(outcome.mission, self.uav_id), outcome)

    def _resume_course(self, now: float) -> None:
        """Track the course again; resent until echoed, across a link outage too, for an
        aircraft left tracking a target it gave up would fly it beside its new holder.
        Only a newer track (a new target, the operator's) or a cancel ends it early."""
        if not self.enabled:
            return
        # No course seen yet (a restart on the target route): the flight plan's start,
        # as the target waypoint's own `next` is then (see `_write_target`).
        back = 0 if self.original_waypoint is None else self.original_waypoint

        def done(result: CommandResult) -> None:
            self._resuming = False
            if not result.ok:
                log.info("resume of waypoint %d ended: %s", back, result.detail)

        self._resuming = True
        self.commands.submit(Track(back), now, done, persistent=True)

    # ---- reporting -----------------------------------------------------------------
    def status(self, text: str, now: float) -> None:
        """A status message: sent on change only (the periodic report is the state)."""
        self.last_status = text
        severity = Severity.of_text(text)
        (log.info if severity == Severity.INFO else log.warning)("%s", text)
        message = StatusText(text, severity)
        self.outputs.publish(keys.status(self.uav_id), message)
        self.outputs.send_ground(message)

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

    def abort_of(self, mission: int) -> MissionAbort | None:
        """The abort of `mission` this UAV obeyed, for a teammate that missed it."""
        if self._abort is None or self._abort.mission != mission:
            return None
        return self._abort

    def own_outcome(self, mission: int) -> TargetOutcome | None:
        if self.round is None or self.round.mission != mission:
            return None
        return self.round.outcome


def _is_target_write(command: AutopilotCommand) -> bool:
    """The target waypoint's write or the track to it (a mission's own target writes)."""
    if isinstance(command, Track):
        return command.waypoint == TARGET_WAYPOINT
    return command.index == TARGET_WAYPOINT
