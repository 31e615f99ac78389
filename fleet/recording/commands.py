"""`fleet record`, `fleet replay`, `fleet plot`, `fleet report` (docs/recording.md).

Exit status: 0 done; 1 the file could not be read or written; 2 usage error or no
Zenoh router; 130 interrupted while replaying.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import zenoh

from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.recording.bus_tap import ended_line
from fleet.recording.mission_log import build_timeline
from fleet.recording.reader import Recording, RecordingError, read_recording, recover
from fleet.recording.recorder import (
    DEFAULT_FIX_EVERY_S,
    DEFAULT_STATE_EVERY_S,
    READY_LINE,
    Recorder,
)
from fleet.recording.replay import DEFAULT_REPLAY_PREFIX, Replayer
from fleet.recording.report import report_json, report_lines
from fleet.recording.thinning import DEFAULT_TELEMETRY_EVERY_S
from fleet.recording.writer import McapSink, Rotation
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import unwrap
from fleet.transport.cli import (
    PREFIX_ENV,
    ExitCode,
    add_verbose_argument,
    add_zenoh_arguments,
    fail,
    non_negative_float,
    positive_float,
    setup_logging,
    stop_on_signals,
)
from fleet.transport.command import (
    Command,
    LocalCommand,
    fields_from,
    key_expr_option,
    options_from,
    run_parsed,
    set_handler,
)
from fleet.transport.zenoh_bus import session_of
from fleet.transport.zenoh_config import error_text

log = logging.getLogger(__name__)

#: A replay's own key space (never $FLEET_KEY_PREFIX, so it is not taken for the fleet).
REPLAY_SPACE = KeySpace(DEFAULT_REPLAY_PREFIX)


def _parse_at(text: str) -> list[Any]:
    # matplotlib (half a second of CPU) only for the command that draws.
    from fleet.recording.plot import parse_at

    return parse_at(text)


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `record`, `replay`, `plot` and `report`."""
    _record_parser(subparsers.add_parser("record", help="record the fleet's key space to MCAP"))
    _replay_parser(subparsers.add_parser("replay", help="replay a recording onto Zenoh"))
    _plot_parser(subparsers.add_parser("plot", help="draw a recorded mission as a PNG"))
    _report_parser(subparsers.add_parser("report", help="each recorded mission, summed up"))


def _record_parser(parser: argparse.ArgumentParser) -> None:
    parser.description = "Record the fleet's key space into an MCAP file until Ctrl-C/SIGTERM."
    parser.add_argument("out", type=Path, metavar="OUT.mcap")
    parser.add_argument("expr", nargs="?", metavar="KEYEXPR", help="what to record ({PREFIX}/**)")
    parser.add_argument("--duration", type=positive_float, metavar="S", help="stop after S s")
    add_zenoh_arguments(parser)
    parser.add_argument(
        "--state-every",
        type=non_negative_float,
        default=DEFAULT_STATE_EVERY_S,
        metavar="S",
        help="query every UAV's state this often, in a fleet of N > 10 every N/10 s at the "
        "shortest; 0: never (default %(default)g s)",
    )
    parser.add_argument(
        "--fix-every",
        type=non_negative_float,
        default=DEFAULT_FIX_EVERY_S,
        metavar="S",
        help="one map fix (foxglove.LocationFix) per UAV this often; 0: one per telemetry "
        "(default %(default)g s)",
    )
    parser.add_argument(
        "--telemetry-every",
        type=non_negative_float,
        default=DEFAULT_TELEMETRY_EVERY_S,
        metavar="S",
        help="one telemetry per UAV in the file this often (the fleet sends 20 Hz); 0: every "
        "one (default %(default)g s)",
    )
    parser.add_argument(
        "--rotate-size", type=positive_float, metavar="MB", help="new file past MB megabytes"
    )
    parser.add_argument(
        "--rotate-every", type=positive_float, metavar="S", help="new file every S seconds"
    )
    parser.add_argument(
        "--recover",
        action="store_true",
        help="do not record: rewrite OUT.mcap, left unfinished by a killed recorder, "
        "into a finished file",
    )
    set_handler(parser, RECORD)


def _replay_parser(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Publish a recording's state (never its commands) again, under another key prefix."
    )
    parser.add_argument("file", type=Path, nargs="+", metavar="FILE.mcap")
    parser.add_argument(
        "--rate", type=positive_float, default=1.0, metavar="K", help="K x real time (1)"
    )
    parser.add_argument(
        "--hold",
        type=non_negative_float,
        default=0.0,
        metavar="S",
        help="keep the UAVs' last state served S seconds after the end (default 0)",
    )
    add_zenoh_arguments(parser)
    # One prefix flag, --key-prefix, as every command has; a replay's own default is
    # `replay`, never $FLEET_KEY_PREFIX, so it is not mistaken for the live fleet.
    set_handler(parser, REPLAY)
    parser.set_defaults(key_space=REPLAY_SPACE)


def _plot_parser(parser: argparse.ArgumentParser) -> None:
    parser.description = "Draw a recorded mission: tracks, targets, assignment, arrivals."
    parser.add_argument("file", type=Path, nargs="+", metavar="FILE.mcap")
    parser.add_argument("--out", type=Path, required=True, metavar="PNG")
    parser.add_argument(
        "--at",
        type=_parse_at,
        default=[],
        metavar="EVENTS",
        help="panels: events (sent,committed,course change,reached,resumed) or seconds, "
        "comma-separated (default: every event seen)",
    )
    parser.add_argument("--mission", type=int, metavar="M", help="which mission (the last)")
    set_handler(parser, PLOT)


def _report_parser(parser: argparse.ArgumentParser) -> None:
    parser.description = "Per mission: team, targets, assignment, agreement, arrivals, faults."
    parser.add_argument("file", type=Path, nargs="+", metavar="FILE.mcap")
    parser.add_argument("--json", action="store_true", help="one JSON object")
    set_handler(parser, REPORT)


# ---- reading -----------------------------------------------------------------
def _read(paths: list[Path], command: str) -> Recording | None:
    try:
        recording = read_recording(paths)
    except RecordingError as error:
        fail(f"fleet {command}", str(error), ExitCode.FAILED)
        return None
    for path, why in recording.truncated.items():
        print(f"fleet {command}: {path} ends early ({why}); read up to there", file=sys.stderr)
    return recording


# ---- fleet record ---------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class RecordOptions:
    out: Path
    #: What to record (None: the key space's every key).
    expr: str | None = None
    duration: float | None = None
    key_space: KeySpace = DEFAULT_SPACE
    state_every: float = DEFAULT_STATE_EVERY_S
    fix_every: float = DEFAULT_FIX_EVERY_S
    telemetry_every: float = DEFAULT_TELEMETRY_EVERY_S
    rotate_size: float | None = None
    rotate_every: float | None = None
    #: Do not record: finish `out`, left unfinished by a killed recorder.
    recover: bool = False


def record_options(args: argparse.Namespace) -> RecordOptions:
    """`record`'s options; a usage error if KEYEXPR is not a key expression."""
    return fields_from(RecordOptions, args, expr=key_expr_option(args.expr))


def run_record(bus: Bus, args: RecordOptions, out: TextIO) -> int:
    if args.recover:
        return _recover(args.out, out)
    rotation = Rotation(
        max_bytes=round((args.rotate_size or 0) * 1_000_000),
        max_seconds=args.rotate_every or 0.0,
    )
    bus = unwrap(bus)  # connected before the file is made: no router, no file
    stop = threading.Event()
    with stop_on_signals(stop.set):
        recorder = Recorder(
            bus,
            McapSink(args.out, rotation),
            expr=args.expr,
            key_space=args.key_space,
            state_every_s=args.state_every,
            on_failure=stop,
            fix_every_s=args.fix_every,
            telemetry_every_s=args.telemetry_every,
        )
        try:
            recorder.start()
        except OSError as error:
            return fail(
                "fleet record", f"cannot write {args.out}: {error.strerror}", ExitCode.FAILED
            )
        except zenoh.ZError as error:
            recorder.stop()
            return fail("fleet record", f"cannot subscribe to {recorder.expr}: {error_text(error)}")
        print(
            f"{READY_LINE} {recorder.expr} to {args.out} (pid {os.getpid()})", file=out, flush=True
        )
        try:
            stop.wait(args.duration)
        finally:
            recorder.stop()
    if recorder.failure is not None:
        return fail("fleet record", f"{recorder.failure}; recording stopped", ExitCode.FAILED)
    files = ", ".join(map(str, recorder.sink.files))
    done = f"fleet record: {recorder.sink.messages} messages in {files}"
    print(ended_line(done, recorder.stats.dropped), file=out, flush=True)
    return ExitCode.OK


def _recover(path: Path, out: TextIO) -> int:
    temporary = path.with_name(path.name + ".recovering")
    try:
        recording = recover(path, temporary)
    except RecordingError as error:
        return fail("fleet record --recover", str(error), ExitCode.FAILED)
    if not recording.messages:
        temporary.unlink(missing_ok=True)
        return fail(
            "fleet record --recover", f"{path} holds no message; left as it is", ExitCode.FAILED
        )
    os.replace(temporary, path)
    why = recording.truncated.get(str(path))
    state = f"it had ended early ({why})" if why else "it was already complete"
    print(
        f"fleet record --recover: {path}: {len(recording.messages)} messages kept; {state}",
        file=out,
    )
    return ExitCode.OK


# ---- fleet replay ---------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class ReplayOptions:
    file: list[Path]
    rate: float = 1.0
    #: Keep the UAVs' last state served this long after the end.
    hold: float = 0.0
    key_space: KeySpace = REPLAY_SPACE


def run_replay(bus: Bus, args: ReplayOptions, out: TextIO) -> int:
    recording = _read(args.file, "replay")
    if recording is None:
        return ExitCode.FAILED
    session = session_of(bus)
    stop = threading.Event()
    with stop_on_signals(stop.set):
        prefix = args.key_space.prefix
        replayer = Replayer(session, recording, prefix=prefix, rate=args.rate, stop=stop)
        print(
            f"fleet replay: {len(recording.messages)} messages at {args.rate:g}x under "
            f"{prefix}/** (see it with {PREFIX_ENV}={prefix} ground-cli watch)",
            file=out,
            flush=True,
        )
        try:
            finished = replayer.run()
            if finished and args.hold > 0:
                print(f"fleet replay: end reached; holding {args.hold:g} s", file=out, flush=True)
                replayer.hold(args.hold)
        finally:
            replayer.close()
    stats = replayer.stats
    print(
        f"fleet replay: {'done' if finished else 'stopped'}: {stats.published} published, "
        f"{stats.skipped} commands and map fixes not replayed, {stats.bad} undecodable",
        file=out,
    )
    return ExitCode.OK if finished else ExitCode.INTERRUPTED


# ---- fleet plot, fleet report ---------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class PlotOptions:
    file: list[Path]
    out: Path
    #: The panels: events or seconds (empty: every event seen).
    at: list[Any] = field(default_factory=list)
    #: Which mission (None: the last).
    mission: int | None = None


def run_plot(args: PlotOptions, out: TextIO) -> int:
    recording = _read(args.file, "plot")
    if recording is None:
        return ExitCode.FAILED
    from fleet.recording.plot import PlotError, render  # matplotlib only to draw

    try:
        drawn = render(
            build_timeline(recording.messages), args.out, mission=args.mission, at=args.at
        )
    except PlotError as error:
        return fail("fleet plot", str(error))
    except OSError as error:
        return fail("fleet plot", f"cannot write {args.out}: {error.strerror}", ExitCode.FAILED)
    print(f"fleet plot: {drawn}", file=out)
    return ExitCode.OK


@dataclass(frozen=True, kw_only=True)
class ReportOptions:
    file: list[Path]
    json: bool = False


def run_report(args: ReportOptions, out: TextIO) -> int:
    recording = _read(args.file, "report")
    if recording is None:
        return ExitCode.FAILED
    timeline = build_timeline(recording.messages)
    if args.json:
        print(json.dumps(report_json(timeline)), file=out)
    else:
        print("\n".join(report_lines(timeline)), file=out)
    return ExitCode.OK


RECORD = Command(record_options, run_record)
REPLAY = Command(options_from(ReplayOptions), run_replay)
PLOT = LocalCommand(options_from(PlotOptions), run_plot)
REPORT = LocalCommand(options_from(ReportOptions), run_report)


def main(argv: list[str] | None = None) -> int:
    """`python -m fleet.recording.commands record ...`: how the launcher starts it."""
    parser = argparse.ArgumentParser(prog="fleet")
    add_verbose_argument(parser)
    add_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    setup_logging(args.verbose)
    return run_parsed(args, f"fleet {args.command}")


if __name__ == "__main__":
    sys.exit(main())
