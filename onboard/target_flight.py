"""Flying a target (thesis 4.3): the waypoint writes, their echoes, arrival, giving up.

Write waypoint TARGET_WAYPOINT at the target with `next` = the waypoint the aircraft was
tracking, then track it; when the autopilot moves on from it, the aircraft is back on
its original course by itself. `flying` once the autopilot echoed the track command,
`reached` once telemetry put the aircraft within REACHED_RADIUS_M of the target, or
once the autopilot moved on from the target waypoint during a link outage that hid the
arrival: to its `next` (the autopilot sequences only on reaching a waypoint: its echo
is the observation), or to any later waypoint when the fixes either side of the outage
say the aircraft could have passed through the target's radius meanwhile
(onboard.outage_arrival), `preempted` when the autopilot left the target route anywhere else or
the ground commanded it directly. A target that cannot be flown (`failure`) is the mission's to
release (onboard.mission_participation).

The flight holds no reference to the mission it is part of: what the mission must act
on (a target reached, a stale target seen) comes back as the `FlightNews` its event
handlers return, which the dispatcher (onboard.core) hands to the mission, and what it
needs of the mission (which mission its commitment belongs to) comes in with `commit`.
"""

from __future__ import annotations

import enum
import logging
from dataclasses import dataclass, field
from typing import Protocol

import msgspec

from fleet.geo.mercator import distance_m
from fleet.mission.key_space import KeySpace
from fleet.mission.lifecycle import Observation
from fleet.mission.messages import CommandResult, NoFlyZone, Target
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.mission.target_checks import REACHED_RADIUS_M
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand, CommandTracker, Completion
from onboard.link_watch import LinkWatch
from onboard.loiter import LOITER_ANCHOR, LOITER_WAYPOINTS, loiter_writes
from onboard.mission_phase import MissionPhase
from onboard.outage_arrival import FixHistory, passed_target
from onboard.route_flight import ROUTE_WAYPOINTS, route_turns, route_writes
from onboard.state_report import Say

log = logging.getLogger(__name__)

#: The waypoint index the module writes a target into (the flight plan keeps the rest).
TARGET_WAYPOINT = 90
#: A target not confirmed by the autopilot this long after the commitment (the writes
#: are retried all along, across link outages) is given up: `failed`, and released.
CONFIRM_LIMIT_S = 20.0
#: A UAV holding a target whose autopilot link stays lost this long is released.
LINK_RELEASE_S = 20.0


class FlightOutputs(Protocol):
    def send_autopilot(self, command: AutopilotCommand) -> None: ...
    def publish(self, key: str, message: msgspec.Struct) -> None: ...


class FlightNews(enum.Enum):
    """What the flight tells the mission it is part of, as an event handler's answer."""

    #: The held target was reached: its outcome to publish, the next of the queue to fly.
    REACHED = enum.auto()
    #: Holding no target, the autopilot tracks the target route (left there before a
    #: restart): once the mission is decided, back to the course (`leave_stale_target`).
    STALE_TARGET = enum.auto()


@dataclass
class TargetFlight:
    uav_id: int
    key_space: KeySpace
    outputs: FlightOutputs
    life: MissionPhase
    link: LinkWatch
    say: Say
    #: The module is on: it writes to the autopilot (OPM).
    enabled: bool = True
    #: A target not echoed this long after the commitment is given up (CONFIRM_LIMIT_S).
    confirm_limit_s: float = CONFIRM_LIMIT_S
    #: A held target whose autopilot link stays lost this long is released (LINK_RELEASE_S).
    link_release_s: float = LINK_RELEASE_S
    tracked_waypoint: int | None = None
    original_waypoint: int | None = None
    commands: CommandTracker = field(init=False)
    #: The mission of the commitment (None: none, or replaced or aborted since).
    mission: int | None = None
    target: int | None = None  #: the target this UAV holds (committed or flying to)
    _target_at: Target | None = None
    _committed_at: float = 0.0
    _target_tracked: bool = False  #: the autopilot echoed the track to the target waypoint
    _target_next: int | None = None  #: where the target waypoint sends the autopilot on
    _outages_when_tracked: int = 0  #: link outages before the target route was echoed
    #: The latest fix, and the last before the latest outage (onboard.outage_arrival).
    _fixes: FixHistory = field(default_factory=FixHistory)
    #: The waypoint the autopilot left the target route for during an outage, while no
    #: fix since the outage tells whether that was the arrival.
    _departed_to: int | None = None
    resuming: bool = False  #: a resume of the course is sent and not echoed yet
    _operator_track: bool = False  #: the ground commanded the target waypoint or its track
    #: The mission's no-fly zones: a target is flown by a route around them.
    zones: tuple[NoFlyZone, ...] = ()
    _no_route: str | None = None  #: why the held target has no route (it then fails)
    #: The turns of the route written to the autopilot for the held target (state report).
    route: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        self.commands = CommandTracker(send=self.outputs.send_autopilot)

    def hold(self, target: int | None, where: Target | None) -> None:
        """Hold `target` (at `where`), or none; its route not echoed yet."""
        self.target, self._target_at = target, where
        self._target_tracked = False
        self._departed_to = None
        self._no_route = None
        self.route = ()

    def _say_of_target(self, kind: StatusKind, text: str, now: float) -> None:
        """A status about the held target, naming it and its mission."""
        self.say(kind, text, now, mission=self.mission, target=self.target)

    # ---- what the autopilot says -------------------------------------------------------
    def on_telemetry(self, now: float) -> FlightNews | None:
        self._fixes.on_fix(self.link.gps, self.link.outages)
        if self.life.holds_target():
            distance = self.target_distance()
            if distance is not None and distance <= REACHED_RADIUS_M:
                return self._reached(distance, now)
            if self._departed_to is not None and self.life.phase == Phase.FLYING:
                # The autopilot left the target route during an outage: judged on the
                # first fix after it.
                return self._left_target_route(self._departed_to, now)
        return None

    def target_distance(self) -> float | None:
        """Metres from the latest GPS fix to the held target; None if either is unknown."""
        gps = self.link.gps
        if self.target is None or gps is None or self._target_at is None:
            return None
        return distance_m((gps.lat, gps.lon), (self._target_at.lat, self._target_at.lon))

    def _reached(self, distance: float, now: float, how: str = "") -> FlightNews:
        # Reached before the track was echoed (it passed by): the target writes still
        # pending would only turn it back to where it has been.
        self.commands.cancel_where(_is_target_write, f"target {self.target} reached")
        self.life.observe(Observation.WITHIN_RADIUS)
        text = f"reached target {self.target} ({how}{distance:.0f} m from it)"
        self._say_of_target(StatusKind.REACHED, text, now)
        return FlightNews.REACHED

    def on_track(self, track: Track, now: float) -> FlightNews | None:
        self.commands.on_echo(track, now)
        previous, self.tracked_waypoint = self.tracked_waypoint, track.waypoint
        if previous != track.waypoint:
            self.outputs.publish(self.key_space.track(self.uav_id), track)
        if _on_target_route(track.waypoint):
            if not _on_target_route(previous) and self.target is None:
                return FlightNews.STALE_TARGET  # a restart's first track, after the re-plan
            return None
        news = None
        flying = self.life.phase == Phase.FLYING
        if flying and self._target_tracked and _on_target_route(previous):
            news = self._left_target_route(track.waypoint, now)
        if not self.life.holds_target() and track.waypoint not in LOITER_WAYPOINTS:
            self.original_waypoint = track.waypoint  # the course to come back to
        return news

    def _left_target_route(self, waypoint: int, now: float) -> FlightNews | None:
        """The autopilot stopped tracking the target: arrival if telemetry says so."""
        self._departed_to = None
        distance = self.target_distance()
        if distance is not None and distance <= REACHED_RADIUS_M:
            return self._reached(distance, now)
        outages = self.link.outages
        if outages > self._outages_when_tracked and distance is not None:
            # A link outage hid what happened: read it from the fixes either side of it
            # (onboard.outage_arrival), however many waypoints the autopilot went through.
            if not self._fixes.fresh_since(outages):
                self._departed_to = waypoint  # no fix since the outage yet: judged on it
                return None
            before, after = self._fixes.before_outage, self._fixes.latest
            passed = (
                before is not None
                and after is not None
                and self._target_at is not None
                and passed_target(before, after, self._target_at, REACHED_RADIUS_M)
            )
            if waypoint == self._target_next or passed:
                how = f"the autopilot moved on to waypoint {waypoint} during a link outage; now "
                return self._reached(distance, now, how)
        where = "unknown distance" if distance is None else f"{distance:.0f} m"
        why = f"autopilot left the target route for waypoint {waypoint} at {where}"
        self.life.observe(Observation.LEFT_ROUTE, why)
        self._say_of_target(StatusKind.NOT_REACHED, f"warning: target not reached: {why}", now)
        return None

    def on_waypoint(self, waypoint: Waypoint, now: float) -> None:
        self.commands.on_echo(waypoint, now)
        self.outputs.publish(self.key_space.waypoint(self.uav_id, waypoint.index), waypoint)

    # ---- what the ground commands --------------------------------------------------------
    def command_autopilot(self, command: AutopilotCommand, now: float, on_done: Completion) -> None:
        """A waypoint or track asked for by the ground; refused while the module is off.

        Commanding the track, or the target waypoint, while holding a target takes the
        aircraft off it: the mission's part is `preempted` at once, with that reason.
        """
        if not self.enabled:
            on_done(CommandResult(False, "module is off: it does not write to the autopilot"))
            return
        retasks = isinstance(command, Track) or _on_target_route(command.index)
        self._operator_track = isinstance(command, Track) and _on_target_route(command.waypoint)
        if retasks and self.life.holds_target():
            what = (
                f"track to waypoint {command.waypoint}"
                if isinstance(command, Track)
                else f"waypoint {command.index}"
            )
            why = f"the ground commanded the autopilot directly ({what})"
            self.commands.cancel_all(why)
            self.life.observe(Observation.OPERATOR_COMMAND, why)
            self._say_of_target(
                StatusKind.TARGET_GIVEN_UP, f"warning: target {self.target} given up: {why}", now
            )
        self.commands.submit(command, now, on_done)

    # ---- flying the mission's target -------------------------------------------------------
    def commit(self, mission: int, target: int, where: Target, now: float) -> None:
        """Hold `target` of `mission` from `now`: the confirm limit runs from here."""
        self.hold(target, where)
        self.mission = mission
        self._committed_at = now

    def superseded(self, mission: int) -> bool:
        """A command's answer arrived after its mission was replaced or aborted (both
        `restart` the flight)."""
        return mission != self.mission

    def write_target(self, mission: int, now: float) -> None:
        """Write the held target's waypoint, then track it; both retried until echoed."""
        target_index, target = self.target, self._target_at
        assert target_index is not None and target is not None
        self._operator_track = False  # the module's own target route from now on
        # on_track never records the target waypoint as the course; 0 before any track.
        back_to = 0 if self.original_waypoint is None else self.original_waypoint
        self._target_next = back_to
        # Around the mission's no-fly zones, the route's turns come first (route_flight).
        gps = self.link.gps
        turns: tuple[tuple[float, float], ...] | None = ()
        speed = self.link.airspeed()
        if self.zones:
            turns = None
            if gps is not None and speed is not None:
                turns = route_turns(gps, target, self.zones, speed)
        if turns is None:
            self._no_route = f"no route around the no-fly zones to target {target_index}"
            return
        # With zones, the target leads to a loiter clear of them, never back to the
        # course, which the module cannot see (onboard.loiter).
        loiter: list[Waypoint] = []
        if self.zones and gps is not None:
            came_from = turns[-1] if turns else (gps.lat, gps.lon)
            loiter = self._loiter(
                (target.lat, target.lon), came_from, target.alt, f"after target {target_index}"
            )
            if loiter:
                back_to = self._target_next = LOITER_ANCHOR
        writes, first = route_writes(TARGET_WAYPOINT, target, turns, back_to)
        writes = [*loiter, *writes]
        self.route = turns

        def write_next(result: CommandResult) -> None:
            if not (result.ok and self._still_committed(mission, target_index)):
                return
            if writes:  # each waypoint once the one it leads to is echoed
                self.commands.submit(writes.pop(0), now, write_next, persistent=True)
            else:
                self.commands.submit(Track(first), now, tracked, persistent=True)

        def tracked(result: CommandResult) -> None:
            if not result.ok or self.superseded(mission) or self.target != target_index:
                return
            self._target_tracked = True
            self._outages_when_tracked = self.link.outages
            if self.life.observe(Observation.TRACK_ECHOED):
                self.say(
                    StatusKind.FLYING_TO_TARGET,
                    f"mission {mission}: flying to target {target_index}",
                    now,
                    mission=mission,
                    target=target_index,
                )

        self.commands.submit(writes.pop(0), now, write_next, persistent=True)

    def _still_committed(self, mission: int, target_index: int) -> bool:
        return (
            not self.superseded(mission)
            and self.target == target_index
            and self.life.phase == Phase.COMMITTED
        )

    def leave_stale_target(self, now: float) -> None:
        """Holding no target, yet the autopilot tracks the target waypoint: left there by
        this module before a restart, and the target is another UAV's now (a re-plan
        released this one while it was away). Back to the course, or it flies it too.
        The mission calls it only once it decided: before, it may still be handed that
        very target."""
        if not _on_target_route(self.tracked_waypoint) or self.resuming or self._operator_track:
            return
        self.say(
            StatusKind.STALE_TARGET_LEFT,
            "warning: the autopilot still tracks the target waypoint of a target this UAV "
            "no longer holds; resuming the course",
            now,
        )
        self.resume_course(now)

    def failure(self, now: float) -> tuple[str, Phase] | None:
        """Why the held target cannot be flown (and the phase that says so), if it cannot:
        its link stayed lost, or the autopilot never echoed its writes in time."""
        if not self.life.holds_target() or self.link.telemetry_at is None:
            return None
        if self._no_route is not None:
            return self._no_route, Phase.FAILED
        silent = now - self.link.telemetry_at
        if silent > self.link_release_s:
            return f"autopilot link lost for {silent:.0f} s", Phase.LINK_LOST
        if self.life.phase == Phase.COMMITTED and now - self._committed_at > self.confirm_limit_s:
            attempts = "over a lost link" if self.link.lost(now) else "with the link up"
            why = (
                f"target writes not echoed by the autopilot within {self.confirm_limit_s:g} s "
                f"(retried {attempts})"
            )
            return why, Phase.FAILED
        return None

    def _loiter(
        self, at: tuple[float, float], came_from: tuple[float, float], alt: float, what: str
    ) -> list[Waypoint]:
        """A loiter's writes at `at`, its leg onward from `came_from` (none found: [],
        and the course it is, as without zones)."""
        # Inflated at the airspeed held, as the routes are.
        speed = self.link.airspeed() or 0.0
        toward = (2.0 * at[0] - came_from[0], 2.0 * at[1] - came_from[1])
        writes = loiter_writes(at, toward, alt, self.zones, speed)
        if writes is None:
            log.warning("no loiter clear of the no-fly zones %s: the course instead", what)
            return []
        return writes

    def resume_course(self, now: float) -> None:
        """Track the course again; resent until echoed, across a link outage too, for an
        aircraft left tracking a target it gave up would fly it beside its new holder.
        Only a newer track (a new target, the operator's) or a cancel ends it early.
        With the mission's no-fly zones, loiter clear of them where it is instead."""
        if not self.enabled:
            return
        # No course seen yet (a restart on the target route): the flight plan's start,
        # as the target waypoint's own `next` is then (see `write_target`).
        back = 0 if self.original_waypoint is None else self.original_waypoint
        gps = self.link.gps
        writes: list[Waypoint] = []
        if self.zones and gps is not None:
            # Onward along its velocity: the loiter's leg starts the way it flies.
            ahead = (gps.lat + gps.vel_north * 1e-5, gps.lon + gps.vel_east * 1e-5)
            writes = self._loiter((gps.lat, gps.lon), ahead, gps.alt, "to wait in")
            if writes:
                back = LOITER_ANCHOR

        def done(result: CommandResult) -> None:
            self.resuming = False
            if not result.ok:
                log.info("resume of waypoint %d ended: %s", back, result.detail)

        def write_next(result: CommandResult) -> None:
            if not result.ok:
                done(result)
            elif writes:
                self.commands.submit(writes.pop(0), now, write_next, persistent=True)
            else:
                self.commands.submit(Track(back), now, done, persistent=True)

        self.resuming = True
        if writes:
            self.commands.submit(writes.pop(0), now, write_next, persistent=True)
        else:
            self.commands.submit(Track(back), now, done, persistent=True)

    def give_up(self, why: str, now: float) -> None:
        """Off the target: every write cancelled, back to the course."""
        self.commands.cancel_all(why)
        self.resume_course(now)

    def restart(self, why: str, now: float) -> None:
        """A new mission, or an abort: every write cancelled; back to the course if a
        target was held or a resume was still pending (a link outage): it goes on."""
        resuming = self.resuming
        self.mission = None  # every answer still to come is to a superseded mission
        self.commands.cancel_all(why)
        if self.life.holds_target() or resuming:
            self.resume_course(now)


def _is_target_write(command: AutopilotCommand) -> bool:
    """A write of the target waypoint or a route turn, or a track to one (a mission's own
    target writes)."""
    return _on_target_route(command.waypoint if isinstance(command, Track) else command.index)


def _on_target_route(waypoint: int | None) -> bool:
    """`waypoint` is the target's, or a turn of the route to it (onboard.route_flight)."""
    return waypoint == TARGET_WAYPOINT or waypoint in ROUTE_WAYPOINTS
