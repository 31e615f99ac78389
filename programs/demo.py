"""`fleet demo`: the thesis's multi-UAV scenario end to end, driven as the ground drives it.

It runs a local fleet (`fleet.launch`) on free ports, sends the scenario's targets to the
team, waits for the consensus and checks that every UAV committed the same assignment,
then watches until every assigned UAV has reached its target, prints who got which
target, and stops everything. Exit 0 when the team agreed and every assigned UAV reached
its target. It is a program of its own, above `ground`: a ground station that starts a
fleet, it uses both the launcher and the mission manager's own code.
"""

from __future__ import annotations

import argparse
import json
import logging
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from fleet.geo.mercator import distance_m
from fleet.launch.launcher import Fleet, FleetSpec, LaunchError
from fleet.launch.up_command import LaunchOptions, common_arguments, recording_path, start_gui
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.status_kind import StatusKind
from fleet.recording.mission_log import build_timeline
from fleet.recording.plot import PlotError, render
from fleet.recording.reader import RecordingError, read_recording
from fleet.sim.scenario import ScenarioError, resolve_scenario
from fleet.transport.bus_factory import opened_bus
from fleet.transport.cli import ExitCode, fail, positive_float, stop_on_signals
from fleet.transport.command import LocalCommand, options_from, set_handler

# The demo is a ground station: it uses the mission manager's own code.
from ground.alerts import StatusRecord
from ground.fleet_view import FleetView
from ground.mission_control import publish_targets
from ground.mission_follower import MissionFollower
from ground.mission_ids import TargetsServer, next_mission_id
from ground.mission_outcome import MissionOutcome

log = logging.getLogger(__name__)

DEMO_SCENARIO = "head_on"
DEMO_SPEEDUP = 10.0
#: Wall seconds the demo waits for every UAV to commit its assignment.
DEMO_COMMIT_TIMEOUT_S = 60.0
#: Wall seconds the demo waits for every assigned UAV to reach its target.
DEMO_REACH_TIMEOUT_S = 300.0
#: A waypoint echo this close to a target (m) is the waypoint the UAV wrote for it.
TARGET_WAYPOINT_MATCH_M = 30.0
#: The mission's picture, drawn from the recording into the log folder.
PLOT_NAME = "mission.png"


def add_demo_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "demo",
        help="the thesis's multi-UAV scenario end to end (head_on)",
        description="Run a scenario end to end on free ports: up, send its targets, "
        "check the consensus, watch every UAV reach its target, stop.",
    )
    parser.add_argument(
        "scenario",
        nargs="?",
        default=DEMO_SCENARIO,
        metavar="SCENARIO",
        help="a scenario with a targets file (default %(default)s)",
    )
    parser.add_argument(
        "--listen",
        metavar="ENDPOINT",
        help="the router's endpoint (default: a free port on 127.0.0.1)",
    )
    parser.add_argument(
        "--timeout",
        type=positive_float,
        default=DEMO_REACH_TIMEOUT_S,
        metavar="S",
        help="wall seconds to wait for the targets to be reached (default %(default)g)",
    )
    parser.add_argument("--json", action="store_true", help="print the outcome as JSON")
    common_arguments(parser, speedup=DEMO_SPEEDUP)
    set_handler(parser, DEMO)
    return parser


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `demo`."""
    add_demo_parser(subparsers)


@dataclass(frozen=True, kw_only=True)
class DemoOptions(LaunchOptions):
    scenario: str = DEMO_SCENARIO
    #: The router's endpoint (None: a free port on 127.0.0.1).
    listen: str | None = None
    #: Wall seconds to wait for the targets to be reached.
    timeout: float = DEMO_REACH_TIMEOUT_S
    json: bool = False
    speedup: float = DEMO_SPEEDUP


# ---- fleet demo -----------------------------------------------------------------------------
def free_tcp_endpoint(host: str = "127.0.0.1") -> str:
    """A tcp endpoint on a port free right now (the OS picks it)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return f"tcp/{host}:{s.getsockname()[1]}"


@dataclass
class Arrival:
    """How a UAV was seen to reach its target."""

    how: str  #: status | phase | track
    after_s: float  #: wall seconds from the commitment


def run_demo(options: DemoOptions, out: TextIO) -> int:
    stop = threading.Event()
    with stop_on_signals(stop.set):
        return _run_demo(options, stop, out)


def _run_demo(args: DemoOptions, stop: threading.Event, out: TextIO) -> int:
    try:
        scenario = resolve_scenario(args.scenario)
        targets = tuple(scenario.targets())
    except (ScenarioError, OSError, ValueError) as error:
        return fail("fleet demo", str(error))
    if not targets:
        return fail("fleet demo", f"scenario {args.scenario} has no targets file")
    spec = FleetSpec(
        scenario=args.scenario,
        listen=args.listen or free_tcp_endpoint(),
        speedup=args.speedup,
        log_dir=args.log_dir,
        start_timeout_s=args.start_timeout,
        key_space=args.key_space,
        fork_onboards=args.fork_onboards,
    )
    say = _sayer(sys.stderr if args.json else out)
    fleet = Fleet(spec, stop_requested=stop)
    say(f"demo: {scenario.description or scenario.name} at speedup {args.speedup:g}")
    say(f"demo: logs in {fleet.log_dir}")
    spec.record = recording_path(fleet, args)
    if spec.record is not None:
        say(f"demo: recording to {spec.record}")
    try:
        with fleet:
            say(f"demo: UAVs {', '.join(map(str, fleet.uav_ids))} alive; router {spec.listen}")
            gui_line = start_gui(fleet, args.gui)
            if gui_line is not None:
                say(f"demo: {gui_line}")
            report = _fly_demo(fleet, targets, args, stop, say)
            if gui_line is not None and not stop.is_set():
                verdict = "success" if report["success"] else "FAILED"
                say(f"demo: {verdict}; the fleet and its page stay up until Ctrl-C (or SIGTERM)")
                stop.wait()
    except LaunchError as error:
        if stop.is_set():
            return fail("fleet demo", "stopped while starting", ExitCode.INTERRUPTED)
        return fail("fleet demo", str(error), ExitCode.FAILED)
    # The recorder finished its file when the fleet stopped: draw the mission from it.
    report["plot"] = _plot(spec.record, fleet.log_dir / PLOT_NAME, say)
    if args.json:
        print(json.dumps(report), file=out)
    else:
        print("\n".join(_demo_summary(report)), file=out)
    return ExitCode.OK if report["success"] else ExitCode.FAILED


def _plot(recording: Path | None, out: Path, say: Callable[[str], None]) -> str | None:
    """Draw the recorded mission into `out`; its path, or None (and why) if it could not."""
    if recording is None:
        return None
    try:
        render(build_timeline(read_recording(recording).messages), out)
    except (RecordingError, PlotError, OSError) as error:
        say(f"demo: no plot: {error}")
        return None
    say(f"demo: plot of the mission in {out}")
    return str(out)


def _sayer(out: TextIO) -> Callable[[str], None]:
    lock = threading.Lock()

    def say(text: str) -> None:
        with lock:
            print(text, file=out, flush=True)

    return say


def _fly_demo(
    fleet: Fleet,
    targets: tuple[Target, ...],
    args: DemoOptions,
    stop: threading.Event,
    say: Callable[[str], None],
) -> dict[str, Any]:
    team = tuple(sorted(fleet.uav_ids))

    last_status: dict[int, str] = {}

    def on_status(status: StatusRecord) -> None:
        # Show only what changed (a module may repeat a summary at its status rate).
        uav, text = status.uav, status.text
        if last_status.get(uav) != text:
            last_status[uav] = text
            say(f"  UAV {uav}: {text}")

    def on_message(kind: str, message: UavResult | AssignmentReport | TargetOutcome) -> None:
        if isinstance(message, AssignmentReport):
            say(f"demo: UAV {message.uav} committed target {message.target}")

    # The demo is its own program's root: it opens its bus once the fleet it started runs.
    with opened_bus(fleet.connect) as bus, FleetView(bus, args.key_space, on_status) as view:
        # A UAV refuses a mission before its first GPS fix, so wait for telemetry.
        deadline = time.monotonic() + args.start_timeout
        while not stop.is_set() and time.monotonic() < deadline:
            if all(v.lat is not None for v in view.snapshot()) and view.live_ids() == list(team):
                break
            view.wait_changed(0.5)
        mission = next_mission_id(bus, args.key_space, 1.0)
        message = MissionTargets(mission=mission, team=team, targets=targets)
        outcome = MissionOutcome(mission=mission, team=team, targets=targets)
        arrivals: dict[int, Arrival] = {}
        with (
            MissionFollower(bus, args.key_space, mission, on_message) as follower,
            TargetsServer(bus, args.key_space, message),
        ):
            sent_wall = time.time()
            publish_targets(bus, args.key_space, message)
            say(f"demo: mission {mission}: {len(targets)} targets sent to the team")
            committed = follower.wait_committed(
                team, min(DEMO_COMMIT_TIMEOUT_S, args.timeout), fetch_every_s=1.0
            )
            follower.fetch(1.0)
            outcome.results, outcome.assignments = follower.snapshot()
            outcome.timed_out = not committed
            committed_at = time.monotonic()
            agreement = outcome.agreement
            say(f"demo: committed: {committed}; agreed: {agreement.agreed}")
            if committed and agreement.agreed:
                arrivals = _watch_arrivals(
                    view, outcome, sent_wall, committed_at, args.timeout, stop, say
                )
    return _demo_report(args, fleet, outcome, arrivals)


def _watch_arrivals(
    view: FleetView,
    outcome: MissionOutcome,
    sent_wall: float,
    committed_at: float,
    timeout_s: float,
    stop: threading.Event,
    say: Callable[[str], None],
) -> dict[int, Arrival]:
    """Wait until every assigned UAV reached its target; returns who did, and how.

    Three signs, any of which counts: a `reached` status message of that UAV
    (sent after the mission went out), its state's mission phase "reached", or its
    track leaving the waypoint it wrote at the target (the waypoint echo within
    TARGET_WAYPOINT_MATCH_M of the target).
    """
    assigned: dict[int, Target] = {}
    for uav in outcome.team:
        index = outcome.target_of(uav)
        if index is not None:
            assigned[uav] = outcome.targets[index]
    arrivals: dict[int, Arrival] = {}
    deadline = time.monotonic() + timeout_s
    next_state = 0.0
    while set(assigned) - set(arrivals) and not stop.is_set() and time.monotonic() < deadline:
        now = time.monotonic()
        if now >= next_state:
            view.refresh_states(1.0)
            next_state = now + 2.0
        states = {v.id: v for v in view.snapshot(include_gone=True)}
        for uav, place in assigned.items():
            if uav in arrivals:
                continue
            how = None
            if any(
                record.uav == uav and record.time >= sent_wall and record.kind is StatusKind.REACHED
                for record in view.recent_records()
            ):
                how = "status"
            elif (
                (state := states.get(uav)) is not None
                and state.mission == outcome.mission
                and state.phase == "reached"
            ):
                how = "phase"
            elif _left_target_waypoint(view, uav, place):
                how = "track"
            if how is not None:
                arrivals[uav] = Arrival(how, time.monotonic() - committed_at)
                say(f"demo: UAV {uav} reached its target ({how})")
        view.wait_changed(0.5)
    return arrivals


def _left_target_waypoint(view: FleetView, uav: int, target: Target) -> bool:
    indices = [
        index
        for index, waypoint in view.waypoints(uav).items()
        if distance_m((target.lat, target.lon), (waypoint.lat, waypoint.lon))
        <= TARGET_WAYPOINT_MATCH_M
    ]
    history = view.track_history(uav)
    for index in indices:
        if index in history:
            last = len(history) - 1 - history[::-1].index(index)
            if last < len(history) - 1:
                return True
    return False


def _demo_report(
    args: DemoOptions, fleet: Fleet, outcome: MissionOutcome, arrivals: dict[int, Arrival]
) -> dict[str, Any]:
    report: dict[str, Any] = outcome.to_json()
    assigned = [uav for uav in outcome.team if outcome.target_of(uav) is not None]
    report.update(
        scenario=args.scenario,
        speedup=args.speedup,
        reached={str(uav): uav in arrivals for uav in outcome.team},
        reached_how={str(uav): a.how for uav, a in arrivals.items()},
        # Wall time x speedup: the simulated flight time, as far as the simulator kept up.
        flown_s={str(uav): round(a.after_s * args.speedup, 1) for uav, a in arrivals.items()},
        log_dir=str(fleet.log_dir),
    )
    report["success"] = bool(
        report["complete"]
        and report["agreed"]
        and assigned
        and all(u in arrivals for u in assigned)
    )
    return report


def _demo_summary(report: dict[str, Any]) -> list[str]:
    lines = [f"demo outcome: mission {report['mission']}, team {report['team']}"]
    for uav in report["team"]:
        key = str(uav)
        target = report["assignment"].get(key)
        eta = report["eta"].get(key)
        flown = report["flown_s"].get(key)
        parts = [f"UAV {uav}: target {target if target is not None else 'none'}"]
        if eta is not None:
            parts.append(f"predicted {eta:.0f} s")
        if target is not None:
            parts.append(
                f"reached after ~{flown:.0f} s simulated" if flown is not None else "NOT reached"
            )
        lines.append("  " + ", ".join(parts))
    lines.append(f"  unassigned targets: {report['unassigned'] or 'none'}")
    lines.append(
        f"  agreed: {'yes' if report['agreed'] else 'no'}"
        + (f" (disagreed: {report['disagreed']})" if report["disagreed"] else "")
    )
    lines.append("demo: success" if report["success"] else "demo: FAILED")
    return lines


DEMO = LocalCommand(options_from(DemoOptions), run_demo)
