"""Start and stop `fleet up` in a loop, and count what goes wrong.

    python -m bench.bench_stress [--cycles 20] [--uavs 4] [--fly 5] [--kill-every 3]
                                 [--measure-every 1] [--fly-other S]
                                 [--fake-runs 0] [--fake-cycles 10] [--keep DIR] [--cores]

For each mode (onboards forked from the fork server, and `--no-fork-server`; the modes
take turns), `--cycles` times: start `fleet up --uavs N --speedup 10` on a free port,
wait until it is ready, let it fly `--fly` seconds, then stop it: with SIGTERM, or every
`--kill-every`-th cycle with SIGKILL. Counted:

* starts that failed, and crashes: a process of the fleet that died of a signal or left
  a "Fatal Python error" (faulthandler's dump) in its log or output;
* after each SIGKILL of the launcher, the processes of its tree still running 10 s
  later (orphans; they are then killed), and how long the tree took to go;
* after each SIGTERM, the recording's telemetry samples per UAV: the smallest UAV's
  count over the median UAV's, over the whole recording and over the window in which
  every UAV is live (from the latest first telemetry of a UAV to the earliest last one):
  the onboards start one after another and are stopped one after another, so over the
  whole recording a UAV started late or stopped early has fewer samples without any
  being lost; over the window, a lost sample counts. Also the longest gap between two
  samples of one UAV in the window (the recording keeps one every 0.2 s, so a gap of
  0.4 s or more is a sample not recorded, or none sent for that long), and, for each
  recording below 5 % over the whole, how late its smallest UAV started and how early
  it ended. With `--measure-every N`, only every Nth SIGTERM cycle flies `--fly` s and
  is measured; the others (SIGKILL cycles too) fly `--fly-other` s (crashes, start
  failures and orphans are counted in all).

A recording keeps a UAV's first telemetry sample 0.2 s or more after the last one it
kept: one every 0.205 s or so on an idle box; a sample that comes late (a process held
up by load) stretches that interval. So a window of W seconds holds about W / 0.205
samples, one more or fewer by where they fall against its edges, fewer where intervals
stretched: two UAVs may differ by two samples with none lost, more than 5 % below about
40 samples (`--fly` 10 or more).

`--fake-runs N` also runs `bench.stress_fakes` N times, each a process of
`--fake-cycles` cycles of the ground tests' fake onboards on an embedded router (with
`--leave-open`, each run also exits with sessions open, which the project closes at
exit unless `--no-exit-close`), and counts the runs that died
of a signal or left faulthandler's dump. `--keep DIR` keeps the logs of every cycle or
run that crashed or failed to start there, and of every recording with a UAV more than
5 % below the median in the window; with `--cores` a crash also leaves its core
dump there (`ulimit -c`, the kernel's core pattern `core` in the crashed process's
working directory), for `gdb`.
"""

from __future__ import annotations

import argparse
import itertools
import os
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from fleet.launch.endpoints import free_port
from fleet.recording.reader import RecordingError, read_recording
from tests.support.processes import descendants, running

READY_S = 180.0
STOP_S = 60.0
#: After a SIGKILL of the launcher, a process of its tree still running this long
#: later is an orphan.
ORPHAN_S = 10.0
CRASH_MARK = "Fatal Python error"
#: Every UAV's telemetry at least this share of the median UAV's: within 5 %.
WITHIN = 0.95
#: A gap this long between two telemetry samples of a UAV in a recording (which keeps
#: one every 0.2 s): a sample not recorded, or none sent for that long (the file cannot
#: tell which).
LOST_GAP_S = 0.4


@dataclass
class ModeResult:
    mode: str
    cycles: int = 0
    ready: int = 0
    start_failures: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    kills: int = 0
    stops: int = 0  #: cycles stopped with SIGTERM
    orphans: int = 0
    gone_s: list[float] = field(default_factory=list)
    recordings: list[TelemetrySpread] = field(default_factory=list)


@dataclass(frozen=True)
class TelemetrySpread:
    """One recording's telemetry per UAV: whole, and in the window every UAV is live."""

    whole: float  #: the smallest UAV's count over the median UAV's, whole recording
    window: float  #: the same, counting only the samples in the window
    window_s: float  #: the window's length
    samples: int  #: the median UAV's samples in the window
    gap_s: float  #: the longest gap between two samples of one UAV in the window
    #: The UAV smallest over the whole: how much later than the earliest it started,
    #: and how much earlier than the latest it ended, seconds.
    late_s: float
    early_s: float


def telemetry_times(path: Path) -> dict[int, list[int]]:
    """Each UAV's telemetry log times (ns), in order; {} if the file cannot be read."""
    times: dict[int, list[int]] = {}
    try:
        recording = read_recording(path)
    except RecordingError:
        return times
    for message in recording.messages:
        parts = message.topic.split("/")
        if len(parts) == 4 and parts[1] == "uav" and parts[3] == "telemetry":
            times.setdefault(int(parts[2]), []).append(message.log_time_ns)
    return times


def spread(times: dict[int, list[int]], uavs: list[int]) -> TelemetrySpread | None:
    """`uavs`' telemetry counts compared, whole and in their common window; None when
    the median UAV has none (or a UAV has none: its ratios are then 0)."""
    whole = {uav: len(times.get(uav, [])) for uav in uavs}
    median = statistics.median(whole.values())
    if median == 0:
        return None
    low = min(uavs, key=lambda uav: whole[uav])
    if whole[low] == 0:
        return TelemetrySpread(0.0, 0.0, 0.0, 0, 0.0, float("inf"), float("inf"))
    start = max(times[uav][0] for uav in uavs)
    end = min(times[uav][-1] for uav in uavs)
    inside = {uav: [t for t in times[uav] if start <= t <= end] for uav in uavs}
    window_median = statistics.median(len(ts) for ts in inside.values())
    gaps = [b - a for ts in inside.values() for a, b in itertools.pairwise(ts)]
    return TelemetrySpread(
        whole=whole[low] / median,
        window=min(len(ts) for ts in inside.values()) / window_median if window_median else 0.0,
        window_s=max(0, end - start) / 1e9,
        samples=int(window_median),
        gap_s=max(gaps, default=0) / 1e9,
        late_s=(times[low][0] - min(times[uav][0] for uav in uavs)) / 1e9,
        early_s=(max(times[uav][-1] for uav in uavs) - times[low][-1]) / 1e9,
    )


def crashes_in(log_dir: Path, output: str) -> list[str]:
    found = [f"fleet up output: {CRASH_MARK}"] if CRASH_MARK in output else []
    for log in sorted(log_dir.glob("*.log")):
        if CRASH_MARK in log.read_text(errors="replace"):
            found.append(f"{log.name}: {CRASH_MARK}")
    found += [f"core dump {core.name}" for core in sorted(log_dir.glob("core*"))]
    return found


def code_env() -> dict[str, str]:
    """The environment of a process started in a cycle's folder (where its core dump
    lands) that runs this checkout's code, not an installed copy."""
    here = str(Path(__file__).resolve().parents[1])
    return {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")])),
    }


def keep(log_dir: Path, keep_dir: Path | None) -> None:
    """The logs (and core dumps) of a cycle that went wrong, kept for a post-mortem."""
    if keep_dir is not None:
        shutil.copytree(log_dir, keep_dir / log_dir.name, dirs_exist_ok=True)


def cycle(result: ModeResult, args: argparse.Namespace, kill: bool, work: Path) -> None:
    result.cycles += 1
    log_dir = work / f"{result.mode}-{result.cycles}"
    log_dir.mkdir()
    out_path = log_dir / "fleet-up.out"
    argv = [sys.executable, "-m", "programs.fleet_cli", "up", "--uavs", str(args.uavs)]
    argv += ["--speedup", "10", "--listen", f"tcp/127.0.0.1:{free_port()}"]
    argv += ["--log-dir", str(log_dir)]
    if result.mode == "no-fork-server":
        argv.append("--no-fork-server")
    with open(out_path, "w") as out:
        up = subprocess.Popen(
            argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True, cwd=log_dir, env=code_env(),
        )  # fmt: skip
    deadline = time.monotonic() + READY_S
    while "stops the fleet" not in out_path.read_text() and up.poll() is None:
        if time.monotonic() > deadline:
            break
        time.sleep(0.2)
    output = out_path.read_text(errors="replace")
    if "stops the fleet" not in output:
        up.kill()
        up.wait()
        result.start_failures.append(f"cycle {result.cycles}: status {up.returncode}")
        result.crashes += [f"cycle {result.cycles}: {c}" for c in crashes_in(log_dir, output)]
        keep(log_dir, args.keep)
        return
    result.ready += 1
    measured = not kill and result.stops % args.measure_every == 0
    time.sleep(args.fly if measured or args.fly_other is None else args.fly_other)
    tree = descendants(up.pid)
    if kill:
        result.kills += 1
        up.send_signal(signal.SIGKILL)
        up.wait()
        killed = time.monotonic()
        while any(running(pid) for pid in tree) and time.monotonic() - killed < ORPHAN_S:
            time.sleep(0.05)
        left = [pid for pid in tree if running(pid)]
        if left:
            result.orphans += len(left)
            for pid in left:
                os.kill(pid, signal.SIGKILL)
        else:
            result.gone_s.append(time.monotonic() - killed)
        crashed = crashes_in(log_dir, out_path.read_text(errors="replace"))
        result.crashes += [f"cycle {result.cycles}: {c}" for c in crashed]
        if crashed or left:
            keep(log_dir, args.keep)
        return
    result.stops += 1
    up.send_signal(signal.SIGTERM)
    try:
        status = up.wait(STOP_S)
    except subprocess.TimeoutExpired:
        up.kill()
        status = up.wait()
    output = out_path.read_text(errors="replace")
    crashed = [f"fleet up died of signal {-status}"] if status < 0 else []
    crashed += crashes_in(log_dir, output)
    result.crashes += [f"cycle {result.cycles}: {c}" for c in crashed]
    if crashed:
        keep(log_dir, args.keep)
    if not measured:
        return
    uavs = list(range(101, 101 + args.uavs))
    telemetry = spread(telemetry_times(log_dir / "fleet.mcap"), uavs)
    if telemetry is not None:
        result.recordings.append(telemetry)
        if telemetry.window < WITHIN:
            keep(log_dir, args.keep)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=20, help="cycles per mode")
    parser.add_argument("--uavs", type=int, default=4)
    parser.add_argument("--fly", type=float, default=5.0, help="seconds flown once ready")
    parser.add_argument(
        "--measure-every", type=int, default=1, help="measure every Nth SIGTERM cycle's recording"
    )
    parser.add_argument(
        "--fly-other", type=float, help="seconds flown by a cycle not measured (default --fly)"
    )
    parser.add_argument("--kill-every", type=int, default=3, help="SIGKILL every Nth cycle")
    parser.add_argument("--modes", default="fork-server,no-fork-server")
    parser.add_argument("--fake-runs", type=int, default=0, help="bench.stress_fakes runs")
    parser.add_argument("--fake-cycles", type=int, default=10, help="cycles per fake run")
    parser.add_argument("--leave-open", action="store_true", help="fake runs exit open")
    parser.add_argument(
        "--no-exit-close", action="store_true", help="fake runs do not close sessions at exit"
    )
    parser.add_argument("--keep", type=Path, help="keep the logs of what crashed here")
    parser.add_argument("--cores", action="store_true", help="let crashes dump core")
    parser.add_argument(
        "--recordings",
        nargs="+",
        type=Path,
        metavar="MCAP",
        help="start nothing: compare these recordings' UAVs (each file's UAVs, from 101)",
    )
    args = parser.parse_args()
    if args.recordings:
        describe_recordings(args.recordings, args.uavs)
        return
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
    if args.cores:
        hard = resource.getrlimit(resource.RLIMIT_CORE)[1]
        resource.setrlimit(resource.RLIMIT_CORE, (hard, hard))
    with tempfile.TemporaryDirectory(prefix="bench-stress-") as folder:
        if args.fake_runs > 0:
            fake_result = ModeResult("fake onboards")
            for _ in range(args.fake_runs):
                fake_run(fake_result, args, Path(folder))
            report(fake_result)
        # The modes take turns, cycle by cycle, so a run stopped early (SIGINT or SIGTERM:
        # the cycle under way ends as usual first) has about as many of each.
        stopping: list[int] = []
        for stop_signal in (signal.SIGINT, signal.SIGTERM):
            signal.signal(stop_signal, lambda signum, _frame: stopping.append(signum))
        results = [ModeResult(mode) for mode in filter(None, args.modes.split(","))]
        started = time.monotonic()
        for n in range(1, args.cycles + 1):
            for result in results:
                if stopping:
                    break
                kill = args.kill_every > 0 and n % args.kill_every == 0
                cycle(result, args, kill, Path(folder))
                # Nothing of a cycle is needed once counted (what went wrong is kept).
                shutil.rmtree(Path(folder) / f"{result.mode}-{result.cycles}")
            progress(results, started)
        if stopping:
            print(f"stopped by signal {stopping[0]} after {n} rounds of {args.cycles}")
        for result in results:
            report(result)


def describe_recordings(paths: list[Path], uavs: int) -> None:
    """Each recording's telemetry per UAV, in the window every UAV is live, one a line:
    what a recording kept by `--keep` shows."""
    ids = list(range(101, 101 + uavs))
    for path in paths:
        times = telemetry_times(path)
        telemetry = spread(times, ids)
        if telemetry is None:
            print(f"{path}: no telemetry")
            continue
        start = max(times[uav][0] for uav in ids)
        end = min(times[uav][-1] for uav in ids)
        per_uav = []
        for uav in ids:
            inside = [t for t in times[uav] if start <= t <= end]
            gap = max((b - a for a, b in itertools.pairwise(inside)), default=0) / 1e9
            per_uav.append(
                f"{uav}: {len(inside)} (first {(inside[0] - start) / 1e9:.2f} s after the "
                f"window's start, last {(end - inside[-1]) / 1e9:.2f} s before its end, "
                f"longest gap {gap:.3f} s)"
                if inside
                else f"{uav}: 0"
            )
        print(
            f"{path}: window {telemetry.window_s:.2f} s, smallest / median "
            f"{telemetry.window:.3f} (whole recording {telemetry.whole:.3f}); " + "; ".join(per_uav)
        )


def progress(results: list[ModeResult], started: float) -> None:
    """A line on stderr per round, to follow a long run."""
    parts = [
        f"{r.mode} {r.cycles} (crashes {len(r.crashes)}, start failures "
        f"{len(r.start_failures)}, orphans {r.orphans}, recordings {len(r.recordings)}, "
        f"below 5 % in the window {sum(t.window < WITHIN for t in r.recordings)})"
        for r in results
    ]
    minutes = (time.monotonic() - started) / 60
    print(f"{time.strftime('%H:%M:%S')} {minutes:.1f} min: " + "; ".join(parts), file=sys.stderr)
    sys.stderr.flush()


def fake_run(result: ModeResult, args: argparse.Namespace, work: Path) -> None:
    """One process of `bench.stress_fakes`: a crash is a signal or faulthandler's dump."""
    result.cycles += 1
    log_dir = work / f"fakes-{result.cycles}"
    log_dir.mkdir()
    argv = [sys.executable, "-m", "bench.stress_fakes", "--cycles", str(args.fake_cycles)]
    if args.leave_open:
        argv.append("--leave-open")
    if args.no_exit_close:
        argv.append("--no-exit-close")
    with open(log_dir / "fakes.log", "w") as out:
        run = subprocess.run(
            argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
            cwd=log_dir, env=code_env(), timeout=READY_S + 60 * args.fake_cycles, check=False,
        )  # fmt: skip
    crashed = [f"died of signal {-run.returncode}"] if run.returncode < 0 else []
    crashed += crashes_in(log_dir, "")
    if run.returncode == 0:
        result.ready += 1
    elif not crashed:
        result.start_failures.append(f"run {result.cycles}: status {run.returncode}")
    result.crashes += [f"run {result.cycles}: {c}" for c in crashed]
    if crashed or run.returncode != 0:
        keep(log_dir, args.keep)


def report(result: ModeResult) -> None:
    gone = f"max {max(result.gone_s):.2f} s" if result.gone_s else "-"
    print(f"{result.mode}: {result.cycles} cycles, {result.ready} ready or ended cleanly")
    print(f"  start failures: {len(result.start_failures)} {result.start_failures}")
    # A crash may leave several marks (a signal, a dump, a core file): cycles count once.
    crashed = len({mark.split(":")[0] for mark in result.crashes})
    print(f"  cycles with a crash: {crashed}; what was seen: {result.crashes}")
    print(f"  SIGTERMs of fleet up: {result.stops}; SIGKILLs: {result.kills}, "
          f"orphans 10 s later: {result.orphans}, tree gone after {gone}")  # fmt: skip
    if result.recordings:
        report_recordings(result.recordings)
    sys.stdout.flush()


def report_recordings(recordings: list[TelemetrySpread]) -> None:
    n = len(recordings)
    for label, ratios in (
        ("whole recording", sorted(r.whole for r in recordings)),
        ("window every UAV is live", sorted(r.window for r in recordings)),
    ):
        within = sum(ratio >= WITHIN for ratio in ratios)
        print(
            f"  recordings: {n}; smallest UAV / median UAV telemetry over the {label}: "
            f"min {ratios[0]:.3f}, median {statistics.median(ratios):.3f}; "
            f"{within} of {n} with every UAV within 5 % of the median"
        )
    windows = sorted(r.window_s for r in recordings)
    samples = sorted(r.samples for r in recordings)
    print(
        f"  the window: {windows[0]:.1f} to {windows[-1]:.1f} s (median "
        f"{statistics.median(windows):.1f}), the median UAV's samples in it {samples[0]} to "
        f"{samples[-1]}; longest gap in a UAV's telemetry in it: "
        f"{max(r.gap_s for r in recordings):.2f} s; recordings with a gap of {LOST_GAP_S} s or "
        f"more (a sample lost, or none sent): {sum(r.gap_s >= LOST_GAP_S for r in recordings)}"
    )
    short = [r for r in recordings if r.whole < WITHIN]
    if short:
        print(
            f"  below 5 % over the whole recording: {len(short)}; their smallest UAV started "
            f"{min(r.late_s for r in short):.2f} to {max(r.late_s for r in short):.2f} s after "
            f"the first and ended {min(r.early_s for r in short):.2f} to "
            f"{max(r.early_s for r in short):.2f} s before the last; of these "
            f"{sum(r.window >= WITHIN for r in short)} within 5 % over the window"
        )


if __name__ == "__main__":
    main()
