"""`ground-cli`: the mission manager (thesis chapter 3) on the command line.

Connects as a Zenoh client to the fleet's router (--connect, else $FLEET_ZENOH_CONNECT,
else tcp/127.0.0.1:7447), or as a Zenoh config file says (--zenoh-config FILE or
$FLEET_ZENOH_CONFIG). Exit status: 0 success; 1 the operation failed (bad targets
file, no UAV, mission not committed or not agreed in time); 2 usage error, bad Zenoh
config or no router.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
import time
from typing import Any, TextIO

import zenoh

from fleet.consensus.deadline import consensus_deadline
from fleet.mission import keys
from fleet.mission.messages import (
    AssignmentReport,
    MissionTargets,
    StatusText,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.mission.targets_file import TargetsFileError
from fleet.transport import bus_codec
from fleet.transport.cli import (
    ExitCode,
    ZenohConfigError,
    add_verbose_argument,
    add_zenoh_arguments,
    bounded_int,
    fail,
    non_negative_float,
    piccolo_id,
    piccolo_ids,
    positive_float,
    setup_logging,
    zenoh_config,
)
from fleet.transport.targets_io import read_targets
from ground import keyspace, targets_command
from ground.fleet_view import fleet_snapshot, format_table, live_uav_ids, query_states
from ground.gui import cli as gui_cli
from ground.mission_control import (
    MissionError,
    mission_status,
    mission_targets_of,
    publish_targets,
    send_abort,
    send_opm,
    wait_delivered,
)
from ground.mission_follower import Listener, MissionFollower
from ground.mission_ids import (
    MAX_MISSION_ID,
    TargetsServer,
    claim_mission,
    contest_grace_s,
    current_mission_id,
    missions_seen,
)
from ground.mission_outcome import MissionOutcome, check_agreement
from ground.session import (
    GroundConnectError,
    decode_sample,
    ground_session,
    live_tokens,
)
from ground.watch import watch

log = logging.getLogger("ground")

#: MissionTargets' own default: how long a UAV waits for its teammates' results.
#: How long `opm` waits for the UAV's status message confirming the change.
OPM_CONFIRM_S = 2.0
#: How long `send-targets` without --wait waits for the team to acknowledge receipt.
DELIVERY_WAIT_S = 3.0
#: How long `abort` waits for every UAV on the mission to report it aborted.
ABORT_CONFIRM_S = 5.0


# ---- argument types -------------------------------------------------------------------------
_mission_id = bounded_int(0, MAX_MISSION_ID, "mission id")


# ---- the parser ---------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ground-cli",
        description="Mission manager for a fleet of Piccolo UAVs over Zenoh.",
        epilog=__doc__.split("\n", 2)[2] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_zenoh_arguments(parser)
    parser.add_argument(
        "--query-timeout",
        type=positive_float,
        default=1.0,
        metavar="S",
        help="how long each Zenoh query waits for answers (default 1 s)",
    )
    add_verbose_argument(parser)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    _add_uavs(commands)
    _add_send_targets(commands)
    _add_watch(commands)
    _add_opm(commands)
    _add_abort(commands)
    _add_mission(commands)
    _add_targets(commands)
    _add_keys(commands)
    gui_cli.add_parser(commands)
    return parser


def _add_uavs(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`uavs`: the live UAVs."""
    uavs = commands.add_parser("uavs", help="list the live UAVs")
    uavs.add_argument("--json", action="store_true", help="a JSON list of objects")
    uavs.set_defaults(handler=cmd_uavs)


def _add_send_targets(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`send-targets`: Send Targets (thesis 3.1.4)."""
    send = commands.add_parser("send-targets", help="send a targets file to the team")
    send.add_argument("file", metavar="FILE", help="targets file (thesis format, 24 bytes each)")
    send.add_argument(
        "--team",
        type=piccolo_ids,
        metavar="ID,ID,...",
        help="Piccolo IDs of the team (default: every live UAV)",
    )
    send.add_argument(
        "--wait",
        action="store_true",
        help="follow the mission until every UAV has committed its assignment",
    )
    send.add_argument(
        "--timeout",
        type=positive_float,
        default=60.0,
        metavar="S",
        help="how long --wait waits (default 60 s)",
    )
    send.add_argument(
        "--deadline",
        type=positive_float,
        metavar="S",
        help="how long each UAV waits for its teammates' results (default: 10 s, longer "
        "for a large team: 2 x (planning budget + 0.1 s per UAV))",
    )
    send.add_argument(
        "--mission",
        type=_mission_id,
        metavar="M",
        help="mission id (default: one more than the highest mission seen)",
    )
    send.add_argument("--json", action="store_true", help="print the outcome as one JSON object")
    send.set_defaults(handler=cmd_send_targets)


def _add_watch(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`watch`: the table and the status box."""
    watch_cmd = commands.add_parser("watch", help="live table of the fleet and its status box")
    watch_cmd.add_argument(
        "--count", type=bounded_int(1, what="count"), metavar="N", help="stop after N tables"
    )
    watch_cmd.add_argument(
        "--duration", type=positive_float, metavar="S", help="stop after S seconds"
    )
    watch_cmd.add_argument(
        "--interval", type=positive_float, default=1.0, metavar="S", help="table period (1 s)"
    )
    watch_cmd.set_defaults(handler=cmd_watch)


def _add_opm(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`opm`: the onboard planning module on or off."""
    opm = commands.add_parser("opm", help="turn a UAV's onboard planning module on or off")
    opm.add_argument("uav", type=piccolo_id, metavar="ID")
    opm.add_argument("state", choices=("on", "off"))
    opm.add_argument(
        "--status-rate",
        type=non_negative_float,
        default=1.0,
        metavar="HZ",
        help="status messages a second; 0: only on change (default 1)",
    )
    opm.set_defaults(handler=cmd_opm)


def _add_abort(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`abort`: end a mission."""
    abort = commands.add_parser("abort", help="abort the current mission (team or one UAV)")
    abort.add_argument(
        "--mission", type=_mission_id, metavar="M", help="mission id (default: the latest seen)"
    )
    abort.add_argument(
        "--uav",
        type=piccolo_id,
        metavar="ID",
        help="abort this UAV alone; its teammates fly on (default: the whole team)",
    )
    abort.set_defaults(handler=cmd_abort)


def _add_mission(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`mission`: a mission's status as the fleet reports it now."""
    status = commands.add_parser(
        "mission", help="a mission's targets: reached (by whom), assigned or unserved"
    )
    status.add_argument(
        "--mission", type=_mission_id, metavar="M", help="mission id (default: the latest seen)"
    )
    status.add_argument(
        "--until-reached",
        type=positive_float,
        metavar="S",
        help="first wait up to S seconds for every target to be reached; exit 0 only if so",
    )
    status.add_argument("--json", action="store_true", help="print it as one JSON object")
    status.set_defaults(handler=cmd_mission)


def _add_targets(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`targets make|show`: Save and Load Targets."""
    targets = commands.add_parser("targets", help="make or show a targets file")
    targets_commands = targets.add_subparsers(dest="targets_command", required=True)
    make = targets_commands.add_parser(
        "make",
        help="write a targets file (Save Targets)",
        description="Write a targets file. Put `--` before a target starting with '-'.",
    )
    make.add_argument("--out", required=True, metavar="FILE")
    make.add_argument("targets", nargs="+", metavar="LAT,LON,ALT")
    make.set_defaults(handler=cmd_targets_make)
    show = targets_commands.add_parser("show", help="read a targets file (Load Targets)")
    show.add_argument("file", metavar="FILE")
    show.add_argument("--json", action="store_true")
    show.set_defaults(handler=cmd_targets_show)


def _add_keys(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`keys`: the key space."""
    keys_cmd = commands.add_parser("keys", help="the key space and each key's latest value")
    keys_cmd.add_argument(
        "expr",
        nargs="?",
        default=None,
        metavar="EXPR",
        help="(everything under the key prefix: fleet/**)",
    )
    keys_cmd.add_argument("--admin", action="store_true", help="the router's admin space too")
    keys_cmd.add_argument(
        "--window",
        type=non_negative_float,
        default=1.0,
        metavar="S",
        help="how long to listen for published-only keys (default 1 s)",
    )
    keys_cmd.add_argument("--full", action="store_true", help="do not shorten long values")
    keys_cmd.add_argument("--json", action="store_true", help="a JSON list of objects")
    keys_cmd.set_defaults(handler=cmd_keys)


# ---- commands ---------------------------------------------------------------------------------
def cmd_uavs(args: argparse.Namespace) -> int:
    with ground_session(args.zenoh) as session:
        views = fleet_snapshot(session, args.query_timeout)
    if args.json:
        print(json.dumps([v.to_json() for v in views]))
    elif views:
        print(format_table(views))
    else:
        print("no live UAV")
    return ExitCode.OK


def _progress_printer(out: TextIO, team: tuple[int, ...]) -> Listener:
    """Prints each result and commitment as it arrives, with the count so far.

    Once every team UAV has committed, says whether they agree (same digest and pairs).
    """
    # Results and reports arrive on Zenoh threads, possibly two at once.
    lock = threading.Lock()
    results: set[int] = set()
    reports: dict[int, AssignmentReport] = {}

    def on_message(kind: str, message: UavResult | AssignmentReport | TargetOutcome) -> None:
        with lock:
            if isinstance(message, UavResult):
                results.add(message.uav)
                times = ", ".join("-" if t is None else f"{t:.1f}" for t in message.times)
                lines = [
                    f"mission {message.mission}: UAV {message.uav} result: [{times}] s "
                    f"({len(results & set(team))}/{len(team)} results)"
                ]
            elif isinstance(message, TargetOutcome):
                why = f" ({message.reason})" if message.reason else ""
                lines = [
                    f"mission {message.mission}: UAV {message.uav} {message.phase} "
                    f"target {message.target}{why}"
                ]
            else:
                reports[message.uav] = message
                target = "none" if message.target is None else str(message.target)
                eta = "" if message.eta_s is None else f", ETA {message.eta_s:.0f} s"
                lines = [
                    f"mission {message.mission}: UAV {message.uav} committed target "
                    f"{target}{eta}, digest {message.digest[:12]} "
                    f"({len(reports.keys() & set(team))}/{len(team)} committed)"
                ]
                agreement = check_agreement(team, reports)
                if not agreement.missing:
                    verdict = "agree" if agreement.agreed else "DISAGREE"
                    lines.append(f"mission {message.mission}: every UAV committed: they {verdict}")
            print("\n".join(lines), file=out, flush=True)

    return on_message


def _summary(outcome: MissionOutcome) -> list[str]:
    agreement = outcome.agreement
    lines = [
        f"mission {outcome.mission}: team {', '.join(map(str, outcome.team))}; "
        f"{len(outcome.targets)} targets"
    ]
    for uav in outcome.team:
        result = outcome.results.get(uav)
        report = outcome.assignments.get(uav)
        times = (
            "no result"
            if result is None
            else "times " + ", ".join("-" if t is None else f"{t:.1f}" for t in result.times) + " s"
        )
        if report is None:
            choice = "not committed"
        elif report.target is None:
            choice = "no target"
        else:
            eta = "" if report.eta_s is None else f" ETA {report.eta_s:.0f} s"
            choice = f"target {report.target}{eta}"
        if uav in outcome.lost:
            choice = "LOST (liveliness gone) " + choice
        elif uav in outcome.declined:
            choice = "declined " + choice
        phase = outcome.phases.get(uav)
        reason = outcome.reasons.get(uav)
        state = f"; phase {phase}" + (f" ({reason})" if reason else "") if phase else ""
        lines.append(f"  UAV {uav}: {choice}; {times}{state}")
    if outcome.epoch:
        lines.append(f"  re-planned: epoch {outcome.epoch}")
    for target in outcome.target_states():
        if target["state"] == "unserved":
            lines.append(f"  target {target['index']}: unserved: {target['reason']}")
        elif target["state"] == "reached":
            lines.append(f"  target {target['index']}: reached by UAV {target['uav']}")
    unassigned = outcome.unassigned()
    lines.append(f"  unassigned targets: {', '.join(map(str, unassigned)) or 'none'}")
    if outcome.superseded_by is not None:
        lines.append(
            f"  SUPERSEDED by mission {outcome.superseded_by}: the team no longer flies "
            f"mission {outcome.mission}"
        )
    if agreement.agreed:
        digest = agreement.reference.digest[:12] if agreement.reference else ""
        lines.append(f"  agreed: yes (digest {digest})")
    else:
        why = []
        if agreement.disagreed:
            why.append("disagreed: " + ", ".join(map(str, agreement.disagreed)))
        if agreement.missing:
            why.append("not committed: " + ", ".join(map(str, agreement.missing)))
        lines.append(f"  agreed: no ({'; '.join(why)})")
    return lines


def cmd_send_targets(args: argparse.Namespace) -> int:
    # The file is read and checked before anything touches the network: a bad file
    # sends nothing.
    try:
        targets = tuple(read_targets(args.file))
    except TargetsFileError as error:
        print(f"error: {error}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    except OSError as error:
        print(f"error: cannot read {args.file}: {error.strerror}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    progress = sys.stderr if args.json else sys.stdout
    with ground_session(args.zenoh) as session:
        team = _team(session, args)
        if not team:
            print("error: no live UAV to send to (name the team with --team)", file=sys.stderr)
            return ExitCode.FAILED

        deadline_s = args.deadline or consensus_deadline(len(team))

        def make(mission: int) -> MissionTargets:
            return MissionTargets(mission, team, targets, deadline_s=deadline_s)

        try:
            with claim_mission(session, make, args.query_timeout, mission=args.mission) as server:
                outcome = _send_and_follow(session, server, args, progress)
        except MissionError as error:
            print(f"error: {error}; nothing sent", file=sys.stderr)
            return ExitCode.FAILED
    if args.json:
        print(json.dumps(outcome.to_json()))
    elif args.wait:
        print("\n".join(_summary(outcome)))
    if not args.wait:
        return ExitCode.OK
    return ExitCode.OK if outcome.succeeded else ExitCode.FAILED


def _send_and_follow(
    session: zenoh.Session, server: TargetsServer, args: argparse.Namespace, progress: TextIO
) -> MissionOutcome:
    """Put the claimed mission and, with --wait, follow it to its commitments (and, when
    another ground contested its id, for as long as that ground's mission may take)."""
    message = server.targets
    mission, team, targets = message.mission, message.team, message.targets
    listener = _progress_printer(progress, team) if args.wait else None
    outcome = MissionOutcome(mission=mission, team=team, targets=targets)
    with MissionFollower(session, mission, listener, team) as follower:
        publish_targets(session, message)
        print(
            f"mission {mission}: {len(targets)} targets from {args.file} sent to "
            f"{', '.join(map(str, team))}",
            file=progress,
            flush=True,
        )
        if args.wait:
            committed = follower.wait_committed(team, args.timeout, fetch_every_s=1.0)
            outcome.timed_out = not committed and follower.superseded_by is None
            if committed and server.contested.is_set():
                grace = contest_grace_s(args.query_timeout)
                print(
                    f"mission {mission}: another ground chose this id too; watching "
                    f"{grace:g} s for its mission",
                    file=progress,
                    flush=True,
                )
                follower.wait_superseded(grace)
        else:
            _report_delivery(session, message, min(DELIVERY_WAIT_S, args.timeout), progress)
        follower.fetch(args.query_timeout)
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
        outcome.lost = set(follower.lost) & set(team)
        if args.wait:
            _read_phases(session, outcome, follower, args.query_timeout)
    return outcome


def _team(session: zenoh.Session, args: argparse.Namespace) -> tuple[int, ...]:
    """`--team`, or every live UAV; team members not live now are warned about."""
    live = live_uav_ids(session, args.query_timeout)
    if not args.team:
        return tuple(live)
    absent = [uav for uav in args.team if uav not in live]
    if absent:
        print(
            f"warning: not live now: {', '.join(map(str, absent))}; they can fetch "
            "the mission while this command runs",
            file=sys.stderr,
        )
    return tuple(args.team)


def _report_delivery(
    session: zenoh.Session, message: MissionTargets, timeout_s: float, out: TextIO
) -> None:
    """Without --wait: say which team UAVs have not acknowledged the mission yet."""
    got = wait_delivered(session, message.mission, message.team, timeout_s)
    missing = [uav for uav in message.team if uav not in got]
    if missing:
        print(
            f"mission {message.mission}: not yet acknowledged by {', '.join(map(str, missing))}",
            file=out,
        )


def _read_phases(
    session: zenoh.Session, outcome: MissionOutcome, follower: MissionFollower, timeout_s: float
) -> None:
    """Each team UAV's phase (and reason) as its own state query answers it; a team UAV
    on a later mission means this one was superseded."""
    for uav, state in query_states(session, timeout_s).items():
        if uav in outcome.team:
            outcome.phases[uav] = str(state.phase)
            if state.reason:
                outcome.reasons[uav] = state.reason
            if state.mission is not None:
                follower.note_later_mission(state.mission.mission)
    outcome.superseded_by = follower.superseded_by


def cmd_watch(args: argparse.Namespace) -> int:
    with ground_session(args.zenoh) as session:
        watch(
            session,
            sys.stdout,
            count=args.count,
            duration_s=args.duration,
            interval_s=args.interval,
            query_timeout_s=min(args.query_timeout, args.interval),
        )
    return ExitCode.OK


def cmd_opm(args: argparse.Namespace) -> int:
    enabled = args.state == "on"
    with ground_session(args.zenoh) as session:
        if not live_tokens(session, keys.alive(args.uav), args.query_timeout):
            print(
                f"error: UAV {args.uav} is not live (no {keys.alive(args.uav)} token); "
                "nothing sent",
                file=sys.stderr,
            )
            return ExitCode.FAILED
        confirmed = threading.Event()
        answer: list[str] = []

        def on_status(sample: Any) -> None:
            status = decode_sample(sample, StatusText)
            if status is not None and status.text.startswith(("module", "error: OPM")):
                answer.append(status.text)
                confirmed.set()

        # Listen before sending: the UAV answers with a status message at once.
        with session.declare_subscriber(keys.status(args.uav), on_status):
            send_opm(session, args.uav, enabled, args.status_rate)
            print(f"UAV {args.uav}: planning module {args.state} sent")
            if confirmed.wait(OPM_CONFIRM_S):
                print(f"UAV {args.uav}: {answer[0]}")
            else:
                print(f"UAV {args.uav}: no confirmation within {OPM_CONFIRM_S:g} s")
    return ExitCode.OK


def cmd_mission(args: argparse.Namespace) -> int:
    with ground_session(args.zenoh) as session:
        mission = args.mission
        if mission is None:
            mission = current_mission_id(session, args.query_timeout)
        if mission is None:
            print("error: no mission seen (give --mission)", file=sys.stderr)
            return ExitCode.FAILED
        try:
            outcome = mission_status(session, mission, args.query_timeout, args.until_reached)
        except MissionError as error:
            print(f"error: {error}", file=sys.stderr)
            return ExitCode.FAILED
    if args.json:
        print(json.dumps(outcome.to_json()))
    else:
        print("\n".join(_summary(outcome)))
    if args.until_reached is not None:
        every = len(outcome.reached_by()) == len(outcome.targets)
        return ExitCode.OK if every else ExitCode.FAILED
    return ExitCode.OK if outcome.succeeded else ExitCode.FAILED


def cmd_abort(args: argparse.Namespace) -> int:
    with ground_session(args.zenoh) as session:
        seen = missions_seen(session, args.query_timeout)
        mission = args.mission
        if mission is None:
            mission = max(seen, default=None)
            if mission is None:
                print("error: no mission to abort (none seen; give --mission)", file=sys.stderr)
                return ExitCode.FAILED
        elif mission not in seen:
            known = ", ".join(map(str, sorted(seen))) or "none"
            print(
                f"error: mission {mission} is unknown to the fleet (missions seen: {known}); "
                "nothing sent",
                file=sys.stderr,
            )
            return ExitCode.FAILED
        send_abort(session, mission, args.uav)
        to = "" if args.uav is None else f" to UAV {args.uav}"
        print(f"mission {mission}: abort sent{to}")
        return _confirm_abort(session, mission, args.uav, args.query_timeout)


def _confirm_abort(session: zenoh.Session, mission: int, uav: int | None, timeout_s: float) -> int:
    """Wait until every UAV aborted (the mission's team, or `uav` alone) reports it.

    A team UAV that does not answer at all (frozen, cut off) has not confirmed: it is
    named, and the exit code says so.
    """
    deadline = time.monotonic() + max(ABORT_CONFIRM_S, timeout_s)
    try:
        team = set(mission_targets_of(session, mission, timeout_s).team)
    except MissionError:
        team = set()  # nobody serves the targets: judge by the states alone
    expected = {uav} if uav is not None else team
    pending: dict[int, str] = {}
    while True:
        states = query_states(session, timeout_s)
        on_mission = {
            piccolo_id
            for piccolo_id, state in states.items()
            if state.mission is not None
            and state.mission.mission == mission
            and (uav is None or piccolo_id == uav)
        }
        pending = {
            piccolo_id: str(state.mission.phase)
            for piccolo_id, state in states.items()
            if piccolo_id in on_mission
            and state.mission is not None
            and state.mission.phase != Phase.ABORTED
        }
        # A team UAV that left for a later mission is off this one; a silent one is not.
        silent = expected - states.keys()
        pending.update({piccolo_id: "no answer" for piccolo_id in silent})
        if not pending or time.monotonic() >= deadline:
            break
        time.sleep(0.2)  # polling the UAVs' state: each query is itself an observation
    confirmed = sorted(on_mission - set(pending))
    print(f"mission {mission}: aborted by {', '.join(map(str, confirmed)) or 'no UAV'}")
    if uav is not None and uav not in on_mission and uav not in pending:
        print(f"error: UAV {uav} is not on mission {mission}", file=sys.stderr)
        return ExitCode.FAILED
    if pending:
        still = ", ".join(f"{p} ({phase})" for p, phase in sorted(pending.items()))
        print(f"error: mission {mission}: not confirmed by {still}", file=sys.stderr)
        return ExitCode.FAILED
    return ExitCode.OK


def cmd_targets_make(args: argparse.Namespace) -> int:
    try:
        targets = targets_command.make(args.out, args.targets)
    except (targets_command.TargetSyntaxError, TargetsFileError) as error:
        print(f"error: {error}; {args.out} not written", file=sys.stderr)
        return ExitCode.FAILED
    except OSError as error:
        print(f"error: cannot write {args.out}: {error.strerror}", file=sys.stderr)
        return ExitCode.FAILED
    print(f"{args.out}: {len(targets)} targets written")
    return ExitCode.OK


def cmd_targets_show(args: argparse.Namespace) -> int:
    try:
        targets: list[Target] = targets_command.show(args.file)
    except TargetsFileError as error:
        print(f"error: {error}", file=sys.stderr)
        return ExitCode.FAILED
    except OSError as error:
        print(f"error: cannot read {args.file}: {error.strerror}", file=sys.stderr)
        return ExitCode.FAILED
    if args.json:
        print(targets_command.targets_json(targets))
    else:
        print(targets_command.targets_table(targets))
    return ExitCode.OK


def cmd_keys(args: argparse.Namespace) -> int:
    with ground_session(args.zenoh) as session:
        values = keyspace.collect(
            session,
            args.expr or keyspace.default_expr(),
            window_s=args.window,
            timeout_s=args.query_timeout,
            admin=args.admin,
        )
    if args.json:
        print(json.dumps([v.to_json() for v in values]))
    else:
        for line in keyspace.format_lines(values, full=args.full):
            print(line)
    return ExitCode.OK


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.verbose, base=logging.WARNING)
    # Making and showing targets files is offline: a Zenoh config cannot stop it.
    if args.command != "targets":
        try:
            args.zenoh = zenoh_config(args)
        except ZenohConfigError as error:
            return fail("ground-cli: error", str(error))
    try:
        status: int = args.handler(args)
    except GroundConnectError as error:
        return fail("ground-cli: error", str(error))
    except KeyboardInterrupt:
        return ExitCode.INTERRUPTED
    finally:
        _report_drops()
    return status


def _report_drops() -> None:
    """Say how many bus messages were refused (each was logged when it arrived)."""
    if bus_codec.DROPPED.total():
        reasons = ", ".join(f"{n} {why}" for why, n in sorted(bus_codec.DROPPED.counts().items()))
        log.warning("refused %d message(s) from the bus: %s", bus_codec.DROPPED.total(), reasons)


if __name__ == "__main__":
    sys.exit(main())
