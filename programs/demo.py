"""`fleet demo`: the thesis's multi-UAV scenario end to end, driven as the ground drives it.

It runs a local fleet (`fleet.launch`) on free ports, sends the scenario's targets to the
team, waits for the consensus and checks that every UAV committed the same assignment,
then watches each UAV fly its whole queue until every target is reached (as the UAV that
reached it says, in its own outcome), prints who reached which target and when, and
stops everything. Exit 0 when the team agreed and every target was reached. It is a
program of its own, above `ground`: a ground station that starts a fleet, it uses both
the launcher and the mission manager's own code.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from fleet.launch.launcher import Fleet, FleetSpec, LaunchError
from fleet.launch.up_command import LaunchOptions, common_arguments, recording_path, start_gui
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.recording.mission_log import build_timeline
from fleet.recording.reader import RecordingError, read_recording
from fleet.sim.scenario import ScenarioError, resolve_scenario
from fleet.transport.bus_factory import opened_bus
from fleet.transport.cli import ExitCode, fail, positive_float, stop_on_signals
from fleet.transport.command import LocalCommand, add_command, options_from

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
#: Wall seconds the demo waits for every target to be reached (whole queues).
DEMO_REACH_TIMEOUT_S = 300.0
#: The mission's picture, drawn from the recording into the log folder.
PLOT_NAME = "mission.png"


def add_demo_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    parser = add_command(
        subparsers,
        "demo",
        DEMO,
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
#: The router's endpoint unless told: a port the OS picks as the router binds it.
ANY_PORT = "tcp/127.0.0.1:0"


@dataclass(frozen=True)
class Arrival:
    """A target reached: by whom, and when."""

    uav: int
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
        listen=args.listen or ANY_PORT,
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
            ids = ", ".join(map(str, fleet.uav_ids))
            say(f"demo: UAVs {ids} alive; router {fleet.listening or spec.listen}")
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
    from fleet.recording.plot import PlotError, render  # matplotlib only once it draws

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
                arrivals = _watch_targets(follower, outcome, committed_at, args.timeout, stop, say)
    return _demo_report(args, fleet, outcome, arrivals)


def _watch_targets(
    follower: MissionFollower,
    outcome: MissionOutcome,
    committed_at: float,
    timeout_s: float,
    stop: threading.Event,
    say: Callable[[str], None],
) -> dict[int, Arrival]:
    """Wait until every target is reached, each UAV flying its whole queue (or until no
    target is left that a UAV still flies to); returns each target reached, by whom and
    when. A target is reached when the UAV that reached it says so in its own outcome."""
    arrivals: dict[int, Arrival] = {}

    def done() -> bool:
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
        for target, uav in sorted(outcome.reached_by().items()):
            if target not in arrivals:
                arrivals[target] = Arrival(uav, time.monotonic() - committed_at)
                say(f"demo: UAV {uav} reached target {target}")
        states = outcome.target_states()
        return stop.is_set() or all(s["state"] != "assigned" for s in states)

    follower.wait_until(done, timeout_s, fetch_every_s=2.0)
    return arrivals


def _demo_report(
    args: DemoOptions, fleet: Fleet, outcome: MissionOutcome, arrivals: dict[int, Arrival]
) -> dict[str, Any]:
    report: dict[str, Any] = outcome.to_json()
    queues = _queues(outcome)
    # Wall time x speedup: the simulated flight time, as far as the simulator kept up.
    simulated = {t: round(a.after_s * args.speedup, 1) for t, a in arrivals.items()}
    report.update(
        scenario=args.scenario,
        speedup=args.speedup,
        # Each UAV: whether it reached every target of its queue.
        reached={
            str(uav): bool(queues.get(uav)) and all(t in arrivals for t in queues[uav])
            for uav in outcome.team
        },
        # Each target reached: by whom, and after how many simulated seconds.
        arrivals={str(t): {"uav": a.uav, "after_s": simulated[t]} for t, a in arrivals.items()},
        # Each UAV: the simulated seconds until its last target, when it reached them all.
        flown_s={
            str(uav): max(simulated[t] for t in queue)
            for uav, queue in queues.items()
            if queue and all(t in arrivals for t in queue)
        },
        log_dir=str(fleet.log_dir),
    )
    report["success"] = bool(
        report["complete"]
        and report["agreed"]
        and outcome.targets
        and all(t in arrivals for t in range(len(outcome.targets)))
    )
    return report


def _queues(outcome: MissionOutcome) -> dict[int, tuple[int, ...]]:
    """Each UAV's queue at the latest epoch (its one target, without queues)."""
    latest = outcome.latest()
    if latest is not None and latest.queues:
        return dict(latest.queues)
    return {
        uav: (target,) for uav in outcome.team if (target := outcome.target_of(uav)) is not None
    }


def _demo_summary(report: dict[str, Any]) -> list[str]:
    lines = [
        f"demo outcome: mission {report['mission']}, team {report['team']}, "
        f"{len(report['targets'])} targets"
    ]
    arrivals = report["arrivals"]
    for uav in report["team"]:
        key = str(uav)
        queue = report["queues"].get(key) or (
            [report["assignment"][key]] if report["assignment"].get(key) is not None else []
        )
        if not queue:
            lines.append(f"  UAV {uav}: no target")
            continue
        legs = []
        for target in queue:
            arrival = arrivals.get(str(target))
            reached = (
                f"reached after ~{arrival['after_s']:.0f} s simulated"
                if arrival is not None and arrival["uav"] == uav
                else "NOT reached"
            )
            legs.append(f"target {target} {reached}")
        lines.append(f"  UAV {uav}: " + "; then ".join(legs))
    lines.append(f"  unassigned targets: {report['unassigned'] or 'none'}")
    lines.append(
        f"  agreed: {'yes' if report['agreed'] else 'no'}"
        + (f" (disagreed: {report['disagreed']})" if report["disagreed"] else "")
    )
    lines.append("demo: success" if report["success"] else "demo: FAILED")
    return lines


DEMO = LocalCommand(options_from(DemoOptions), run_demo)
