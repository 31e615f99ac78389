"""What a recording says about each mission (pure): who, where, when, and what went wrong.

Every event is one observed in the recording, never inferred from a plan:

* sent: the mission's targets message was heard;
* committed: a UAV's assignment report was heard (the mission's: the last team UAV's);
* course change: the UAV's first track change after its commitment (it turned to its
  target waypoint, as its autopilot echoed);
* reached: the UAV said so (a `reached` status message, or state phase "reached"), or
  its track left the target waypoint (the autopilot passed it), whichever was heard
  first;
* resumed: that track change back to its own course;
* ended short: the UAV's part ended without reaching its target: the ground's abort
  (of the team, or of this UAV alone) was heard, or the UAV's state said `aborted`,
  `preempted` or `failed` in this mission. Such a UAV's track change back to its
  course is the abort (or the operator's re-tasking), not an arrival: it is never
  counted as reached, and no flown time is given for it.

Flown time is measured on the aircraft's own clock (telemetry `system_time_ms`) from
the UAV's commitment to its arrival, so it compares with the predicted ETA whatever
the simulator's speedup. Times are seconds since the recording's first message.

A status message recorded before status messages had a kind (no `kind` field) still
reads: it said its UAV arrived when its text starts with "reached" (what the onboard
said then, "reached target N ..."), and it is a fault when the severity it carried is
a warning or an error.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import msgspec

from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    NoFlyZone,
    StatusText,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.no_fly import mission_zone_problem
from fleet.mission.phase import Phase, Severity
from fleet.mission.status_kind import StatusKind
from fleet.recording.reader import RecordedMessage

NS = 1_000_000_000
#: The phases (as recorded) that end a UAV's part short of its target.
_ENDED_SHORT = frozenset({Phase.ABORTED, Phase.PREEMPTED, Phase.FAILED})
#: Tokens that go in the recording's last seconds are the fleet being stopped, not a fault.
SHUTDOWN_S = 2.0


@dataclass
class Track:
    """A UAV's flown positions: (t, lat, lon), and its clock: (t, aircraft seconds)."""

    uav: int
    times: list[float] = field(default_factory=list)
    lat: list[float] = field(default_factory=list)
    lon: list[float] = field(default_factory=list)
    clock: list[float] = field(default_factory=list)

    def until(self, t: float) -> int:
        """How many points were flown by time t."""
        return bisect.bisect_right(self.times, t)

    def aircraft_time(self, t: float) -> float | None:
        """The aircraft's clock (s) at the last telemetry at or before t."""
        i = self.until(t)
        return self.clock[i - 1] if i else None

    def flown_between(self, start: float, stop: float) -> float | None:
        """Seconds of the aircraft's clock from `start` to `stop` (recording times), or
        None where the recording does not tell: no telemetry before `start`, or none
        between the two while they are apart (a gap in the recording is not 0 s flown)."""
        first, last = self.aircraft_time(start), self.aircraft_time(stop)
        if first is None or last is None:
            return None
        if stop > start and self.until(stop) == self.until(start):
            return None
        return last - first

    def position(self, t: float) -> tuple[float, float] | None:
        i = self.until(t)
        return (self.lat[i - 1], self.lon[i - 1]) if i else None


@dataclass
class MissionLog:
    mission: int
    team: tuple[int, ...]
    targets: tuple[Target, ...]
    sent: float
    end: float  #: the next mission's start, or the recording's end
    results: dict[int, UavResult] = field(default_factory=dict)
    assignments: dict[int, AssignmentReport] = field(default_factory=dict)
    committed: dict[int, float] = field(default_factory=dict)
    course_change: dict[int, float] = field(default_factory=dict)
    reached: dict[int, float] = field(default_factory=dict)
    reached_how: dict[int, str] = field(default_factory=dict)
    resumed: dict[int, float] = field(default_factory=dict)
    flown_s: dict[int, float] = field(default_factory=dict)
    #: UAVs whose part ended short of their target: when, and how (aborted, preempted,
    #: failed); never one that reached.
    ended: dict[int, tuple[float, str]] = field(default_factory=dict)
    faults: list[tuple[float, str]] = field(default_factory=list)
    #: The mission's no-fly zones.
    zones: tuple[NoFlyZone, ...] = ()
    #: Each UAV's reached outcomes as heard: (t, target), in order (a queue).
    arrivals: dict[int, list[tuple[float, int]]] = field(default_factory=dict)
    #: The latest re-plan heard (the highest epoch): the survivors' queues, a dropped
    #: UAV's targets appended to them.
    replan: AssignmentReport | None = None
    #: Each UAV's time for each leg as it said when it began the leg (its state's
    #: `leg_s`, the first heard): uav -> target -> seconds.
    leg_said: dict[int, dict[int, float]] = field(default_factory=dict)
    #: Every assignment each UAV put as the one it follows (its assignment key), in the
    #: order heard: (t, report). The plan in force when one of its legs began.
    followed: dict[int, list[tuple[float, AssignmentReport]]] = field(default_factory=dict)
    #: Each UAV's standings for re-plans (results with a `basis`), by (UAV, basis): the
    #: air a resolved re-plan timed its legs in.
    standings: dict[tuple[int, str], UavResult] = field(default_factory=dict)

    def plan_of(self, uav: int) -> AssignmentReport | None:
        """The plan the UAV flew last: the latest re-plan, unless it was released by it
        (its tour is then the one it committed to), else its own commitment."""
        replan = self.replan
        if replan is not None and replan.queues and uav not in replan.released:
            return replan
        return self.assignments.get(uav)

    def queue_of(self, uav: int) -> tuple[int, ...]:
        """The UAV's queue in the plan it flew last (`plan_of`; its one target before
        queues)."""
        report = self.plan_of(uav)
        if report is None:
            return ()
        if report.queues:
            return report.queues.get(uav, ())
        return () if report.target is None else (report.target,)

    def plan_at(self, uav: int, t: float | None) -> tuple[float, AssignmentReport] | None:
        """The plan the UAV followed at `t` (the latest it put at or before it), with when
        it put it; its first commitment where `t` is None or before it."""
        followed = self.followed.get(uav, [])
        if not followed:
            report = self.assignments.get(uav)
            at = self.committed.get(uav)
            return None if report is None or at is None else (at, report)
        if t is None:
            return followed[0]
        before = [entry for entry in followed if entry[0] <= t]
        return before[-1] if before else followed[0]

    def air_result(self, uav: int, report: AssignmentReport) -> UavResult | None:
        """The result whose air `report` timed `uav`'s legs in: its standing for a
        resolved re-plan, else its first result."""
        if report.basis is not None:
            return self.standings.get((uav, report.basis))
        return self.results.get(uav)

    def flown_order(self, uav: int) -> list[int]:
        """The targets the UAV reached, in the order it reached them, then the rest of its
        queue in the plan it flew last (`queue_of`) that nobody was heard to reach."""
        order: list[int] = []
        for _, target in self.arrivals.get(uav, []):
            if target not in order:
                order.append(target)
        anyone = {target for heard in self.arrivals.values() for _, target in heard}
        return order + [t for t in self.queue_of(uav) if t not in order and t not in anyone]

    def leg_plans(self, uav: int) -> list[LegPlan]:
        """Each leg of the UAV's `flown_order`: when it began (the previous arrival, or
        its commitment; or, where it turned to the target mid-leg on a re-plan, that
        re-plan), and the plan in force then, whose time for the leg is `predicted`."""
        reached: dict[int, float] = {}
        for t, target in self.arrivals.get(uav, []):
            reached.setdefault(target, t)
        legs: list[LegPlan] = []
        previous: int | None = None
        for target in self.flown_order(uav):
            begun = self.committed.get(uav) if previous is None else reached.get(previous)
            plan = self.plan_at(uav, begun)
            seconds = None if plan is None else _leg_time(plan[1], uav, previous, target)
            if seconds is None and begun is not None:
                # Not next in the plan in force as the leg began: a later re-plan turned
                # the UAV to it on the way (its new first target): the leg began there.
                turned = self._turned_to(uav, target, begun, reached.get(target))
                if turned is not None:
                    plan, begun = turned, turned[0]
                    seconds = _leg_time(plan[1], uav, None, target)
            legs.append(LegPlan(target, previous, begun, plan, seconds))
            previous = target
        return legs

    def _turned_to(
        self, uav: int, target: int, after: float, until: float | None
    ) -> tuple[float, AssignmentReport] | None:
        """The first plan the UAV put after `after` (and before `until`) whose queue
        starts with `target` for it: the re-plan that turned it there."""
        for at, report in self.followed.get(uav, []):
            if at <= after or (until is not None and at > until):
                continue
            queue = _queue(report, uav)
            if queue and queue[0] == target:
                return at, report
        return None

    def legs(self, uav: int, tracks: dict[int, Track]) -> list[dict[str, Any]]:
        """Each leg of the UAV's `flown_order`: the time the plan in force when it began
        gave it (`leg_plans`; `epoch` names that plan where it is a re-plan's), and the
        time flown (aircraft clock, from when it began to the arrival), None where it was
        not seen reached; and `begun_s`, the UAV's time for the leg said as it began it
        (its state's `leg_s`), where it said one."""
        if self.assignments.get(uav) is None:
            return []
        track = tracks.get(uav)
        reached = {target: t for t, target in self.arrivals.get(uav, [])}
        rows: list[dict[str, Any]] = []
        for leg in self.leg_plans(uav):
            at = reached.get(leg.target)
            flown = None
            if track is not None and at is not None and leg.begun is not None:
                flown = track.flown_between(leg.begun, at)
            row: dict[str, Any] = {
                "target": leg.target,
                "predicted_s": leg.predicted,
                "flown_s": flown,
            }
            if leg.plan is not None and leg.plan[1].epoch:
                row["epoch"] = leg.plan[1].epoch
            said = self.leg_said.get(uav, {}).get(leg.target)
            if said is not None:  # the UAV's time for the leg, said as it began it
                row["begun_s"] = said
            rows.append(row)
        return rows

    def target_of(self, uav: int) -> int | None:
        report = self.assignments.get(uav)
        return report.target if report is not None else None

    def predicted_s(self, uav: int) -> float | None:
        report = self.assignments.get(uav)
        return report.eta_s if report is not None else None

    @property
    def agreed(self) -> bool:
        reports = [self.assignments.get(uav) for uav in self.team]
        if any(r is None for r in reports):
            return False
        return len({(r.digest, tuple(sorted(r.pairs.items()))) for r in reports if r}) == 1

    @property
    def all_committed(self) -> float | None:
        """When the last team UAV committed; None if one never did."""
        if any(uav not in self.committed for uav in self.team):
            return None
        return max(self.committed[uav] for uav in self.team)

    def events(self) -> dict[str, float]:
        """The mission's moments for the figure's panels (those that happened)."""
        found = {"sent": self.sent}
        if self.committed:
            found["committed"] = max(self.committed.values())
        for name, times in (
            ("course change", self.course_change),
            ("reached", self.reached),
        ):
            if times:
                found[name] = max(times.values())
        if self.resumed:
            # Some way past the last turn back, so the resumed courses show.
            last = max(self.resumed.values())
            found["resumed"] = min(self.end, last + max(5.0, 0.25 * (last - self.sent)))
        return found


@dataclass(frozen=True)
class LegPlan:
    """One leg of a UAV's queue and the plan in force when it began."""

    target: int
    previous: int | None  #: the target before it; None for the first
    begun: float | None  #: when it began (recording time)
    plan: tuple[float, AssignmentReport] | None  #: (when put, the plan in force then)
    predicted: float | None  #: that plan's time for the leg (s)


def _queue(report: AssignmentReport, uav: int) -> tuple[int, ...]:
    if report.queues:
        return report.queues.get(uav, ())
    return () if report.target is None or report.uav != uav else (report.target,)


def _leg_time(
    report: AssignmentReport, uav: int, previous: int | None, target: int
) -> float | None:
    """`report`'s time for `uav`'s leg to `target` after `previous`: its arrival there
    less its arrival at the target before in its queue; the arrival itself where the
    target is its queue's first (from where the UAV planned); None where the target is
    not next in its queue after `previous`."""
    queue, arrivals = _queue(report, uav), report.arrivals.get(uav, ())
    if not report.arrivals and report.eta_s is not None and queue[:1] == (target,):
        arrivals = (report.eta_s,)
    if target not in queue:
        return None
    j = queue.index(target)
    if j >= len(arrivals):
        return None
    if j == 0:
        return arrivals[0]
    if previous is not None and previous not in queue:
        return None
    return arrivals[j] - arrivals[j - 1]


@dataclass
class Timeline:
    """Everything the figures and the report need from a recording."""

    start_ns: int
    end: float
    tracks: dict[int, Track]
    missions: list[MissionLog]
    undecodable: int = 0


# ---- reading the messages ----------------------------------------------------------------------
@dataclass(frozen=True)
class _Said:
    """A status message, as much of it as the timeline needs."""

    t: float
    uav: int
    text: str
    reached: bool  #: it says the UAV arrived at its target
    fault: bool  #: a warning or an error
    mission: int | None = None  #: the mission it speaks of, where it names one


def _said(t: float, uav: int, value: dict[str, Any]) -> _Said:
    status = msgspec.convert(value, StatusText, str_keys=True)
    if "kind" in value:
        reached, severity = status.kind is StatusKind.REACHED, status.severity
    else:  # recorded before status kinds (see the module's docstring)
        reached = status.text.startswith("reached")
        severity = msgspec.convert(value.get("severity", Severity.INFO), Severity)
    return _Said(t, uav, status.text, reached, severity is not Severity.INFO, status.mission)


def _leaf(topic: str) -> list[str]:
    return topic.split("/")[1:]


def build_timeline(messages: Iterable[RecordedMessage]) -> Timeline:
    ordered = sorted(messages, key=lambda m: m.log_time_ns)
    start = ordered[0].log_time_ns if ordered else 0
    builder = _Builder(start)
    for message in ordered:
        builder.add(message)
    end = (ordered[-1].log_time_ns - start) / NS if ordered else 0.0
    return builder.finish(end)


@dataclass
class _Builder:
    start_ns: int
    tracks: dict[int, Track] = field(default_factory=dict)
    missions: dict[int, MissionLog] = field(default_factory=dict)
    track_changes: dict[int, list[tuple[float, int]]] = field(default_factory=dict)
    statuses: list[_Said] = field(default_factory=list)
    phases: list[tuple[float, int, int, str]] = field(default_factory=list)
    #: (mission, uav, target) -> a UAV's time for the leg, said when it began it
    leg_said: dict[tuple[int, int, int], float] = field(default_factory=dict)
    gone: list[tuple[float, int]] = field(default_factory=list)
    link_down: list[tuple[float, int, str]] = field(default_factory=list)
    link_was_down: dict[int, bool] = field(default_factory=dict)
    #: (t, mission, uav): an abort heard; uav None aborts the team
    aborts: list[tuple[float, int, int | None]] = field(default_factory=list)
    end: float = 0.0
    undecodable: int = 0

    def add(self, message: RecordedMessage) -> None:
        parts = _leaf(message.topic)
        value = message.value()
        if not isinstance(value, dict):
            self.undecodable += 1
            return
        t = (message.log_time_ns - self.start_ns) / NS
        try:
            if parts[:1] == ["uav"] and len(parts) >= 3:
                self._add_uav(t, int(parts[1]), parts[2], value)
            elif parts[:1] == ["mission"] and len(parts) >= 3:
                self._add_mission(t, parts[2], value)
        except (msgspec.ValidationError, ValueError, TypeError, KeyError):
            self.undecodable += 1

    def _add_uav(self, t: float, uav: int, leaf: str, value: Any) -> None:
        if leaf == "telemetry":
            gps = value.get("gps")
            if isinstance(gps, dict):
                # Every field parsed before any is kept: the lists stay the same length.
                lat, lon = float(gps["lat"]), float(gps["lon"])
                clock = float(value["system_time_ms"]) / 1000.0
                if not (math.isfinite(clock) and _on_earth(lat, lon)):
                    raise ValueError("not a position on Earth")
                track = self.tracks.setdefault(uav, Track(uav))
                track.times.append(t)
                track.lat.append(lat)
                track.lon.append(lon)
                track.clock.append(clock)
        elif leaf == "track":
            self.track_changes.setdefault(uav, []).append((t, int(value["waypoint"])))
        elif leaf == "status":
            self.statuses.append(_said(t, uav, value))
        elif leaf == "state":
            mission = value.get("mission")
            if isinstance(mission, dict):
                said = _leg_said(mission)  # parsed first: a bad message adds nothing
                self.phases.append((t, uav, int(mission["mission"]), str(mission["phase"])))
                if said is not None:
                    self.leg_said.setdefault((said[0], uav, said[1]), said[2])
        elif leaf == "alive" and value.get("alive") is False:
            self.gone.append((t, uav))
        elif leaf == "link":
            down = [port for port in ("program", "payload") if not value.get(f"{port}_up")]
            if down and not self.link_was_down.get(uav):
                self.link_down.append((t, uav, " and ".join(down)))  # only when it goes down
            self.link_was_down[uav] = bool(down)

    def _add_mission(self, t: float, kind: str, value: Any) -> None:
        if kind == "targets":
            targets = msgspec.convert(value, MissionTargets, str_keys=True)
            if not all(_on_earth(p.lat, p.lon) for p in targets.targets):
                raise ValueError("a target not on Earth")
            if mission_zone_problem(targets.zones) is not None:
                raise ValueError("a no-fly zone that is not a polygon")
            if targets.mission not in self.missions:
                self.missions[targets.mission] = MissionLog(
                    targets.mission,
                    targets.team,
                    targets.targets,
                    sent=t,
                    end=t,
                    zones=targets.zones,
                )
        elif kind == "result":
            result = msgspec.convert(value, UavResult, str_keys=True)
            if (log := self.missions.get(result.mission)) is None:
                pass
            elif result.basis is not None:
                log.standings.setdefault((result.uav, result.basis), result)
            else:
                log.results.setdefault(result.uav, result)
        elif kind == "assignment":
            report = msgspec.convert(value, AssignmentReport, str_keys=True)
            if (log := self.missions.get(report.mission)) is not None:
                if report.target is not None and not 0 <= report.target < len(log.targets):
                    raise ValueError(f"target {report.target} is not one of the mission's")
                log.assignments.setdefault(report.uav, report)
                log.committed.setdefault(report.uav, t)
                log.followed.setdefault(report.uav, []).append((t, report))
        elif kind == "replan":
            report = msgspec.convert(value, AssignmentReport, str_keys=True)
            log = self.missions.get(report.mission)
            if log is not None and any(
                not 0 <= index < len(log.targets)
                for queue in report.queues.values()
                for index in queue
            ):
                raise ValueError("a re-planned queue names a target that is not the mission's")
            if log is not None and (log.replan is None or report.epoch > log.replan.epoch):
                log.replan = report
        elif kind == "outcome":
            outcome = msgspec.convert(value, TargetOutcome, str_keys=True)
            log = self.missions.get(outcome.mission)
            if log is not None and outcome.phase == Phase.REACHED and outcome.target is not None:
                log.arrivals.setdefault(outcome.uav, []).append((t, outcome.target))
        elif kind == "abort" and (log := self.missions.get(int(value["mission"]))) is not None:
            alone = value.get("uav")
            uav = None if alone is None else int(alone)
            self.aborts.append((t, log.mission, uav))
            who = "" if uav is None else f" for UAV {uav} alone"
            log.faults.append((t, f"mission {log.mission} aborted by the ground{who}"))

    def finish(self, end: float) -> Timeline:
        self.end = end
        ordered = sorted(self.missions.values(), key=lambda m: m.sent)
        for i, log in enumerate(ordered):
            log.end = ordered[i + 1].sent if i + 1 < len(ordered) else end
            for (mission, uav, target), seconds in self.leg_said.items():
                if mission == log.mission:
                    log.leg_said.setdefault(uav, {})[target] = seconds
            self._arrivals(log)
            self._faults(log)
        return Timeline(self.start_ns, end, self.tracks, ordered, self.undecodable)

    def _arrivals(self, log: MissionLog) -> None:
        for uav, committed in log.committed.items():
            if log.target_of(uav) is None:
                continue
            changes = [c for c in self.track_changes.get(uav, []) if log.sent <= c[0] <= log.end]
            after = [c for c in changes if c[0] >= committed]
            if after:
                log.course_change[uav] = after[0][0]
                back = [c for c in after[1:] if c[1] != after[0][1]]
                if back:
                    log.resumed[uav] = back[0][0]
            # A status names its mission: an arrival at an earlier mission's target (the
            # UAV still flying it when this one was committed) is not this one's.
            said = [
                (status.t, "status")
                for status in self.statuses
                if status.uav == uav
                and status.reached
                and status.mission in (None, log.mission)
                and committed <= status.t <= log.end
            ]
            # The outcome the UAV published for its first target, where it was heard.
            first = log.target_of(uav)
            said += [(t, "outcome") for t, target in log.arrivals.get(uav, []) if target == first]
            said += [
                (t, "phase")
                for t, who, mission, phase in self.phases
                if who == uav and mission == log.mission and phase == "reached" and t <= log.end
            ]
            ended = self._ended_short(log, uav)
            if uav in log.resumed and ended is None:
                said.append((log.resumed[uav], "track"))
            if said:
                when, how = min(said)
                log.reached[uav], log.reached_how[uav] = when, how
                self._flown(log, uav, committed, when)
            elif ended is not None:
                log.ended[uav] = ended

    def _ended_short(self, log: MissionLog, uav: int) -> tuple[float, str] | None:
        """When and how the UAV's part in the mission ended short of its target, first
        heard: the ground's abort, or its own state saying aborted, preempted, failed."""
        heard = [
            (t, "aborted")
            for t, mission, who in self.aborts
            if mission == log.mission and who in (None, uav)
        ]
        heard += [
            (t, phase)
            for t, who, mission, phase in self.phases
            if who == uav and mission == log.mission and phase in _ENDED_SHORT and t <= log.end
        ]
        return min(heard) if heard else None

    def _flown(self, log: MissionLog, uav: int, committed: float, reached: float) -> None:
        track = self.tracks.get(uav)
        if track is None:
            return
        flown = track.flown_between(committed, reached)
        if flown is not None:
            log.flown_s[uav] = flown

    def _faults(self, log: MissionLog) -> None:
        team = set(log.team)
        window = (log.sent, log.end)
        for said in self.statuses:
            if said.uav in team and said.fault and _within(said.t, window):
                log.faults.append((said.t, f"UAV {said.uav}: {said.text}"))
        for t, uav in self.gone:
            if uav in team and _within(t, window) and t < self.end - SHUTDOWN_S:
                log.faults.append((t, f"UAV {uav} left (liveliness token gone)"))
        for t, uav, ports in self.link_down:
            if uav in team and _within(t, window):
                log.faults.append((t, f"UAV {uav}: {ports} link down"))
        for uav in log.team:
            if uav not in log.committed:
                log.faults.append((log.end, f"UAV {uav} never committed"))
            elif uav in log.ended:
                t, how = log.ended[uav]
                log.faults.append((t, f"UAV {uav} {how}: its target not reached"))
            elif log.target_of(uav) is not None and uav not in log.reached:
                log.faults.append((log.end, f"UAV {uav} not seen to reach its target"))
        if log.committed and all(u in log.committed for u in log.team) and not log.agreed:
            log.faults.append((max(log.committed.values()), "the team's assignments disagree"))
        log.faults.sort()


def _leg_said(progress: dict[str, Any]) -> tuple[int, int, float] | None:
    """(mission, target, seconds) of a state's `leg_s` (MissionProgress), if it says one."""
    target, seconds = progress.get("current_target"), progress.get("leg_s")
    if target is None or seconds is None:
        return None
    seconds = float(seconds)
    if not math.isfinite(seconds) or seconds < 0.0:
        raise ValueError("a leg time that is not a duration")
    return int(progress["mission"]), int(target), seconds


def _on_earth(lat: float, lon: float) -> bool:
    return abs(lat) < 90 and abs(lon) <= 360


def _within(t: float, window: tuple[float, float]) -> bool:
    return window[0] <= t <= window[1]
