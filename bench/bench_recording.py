"""Benchmark of `fleet record`: what a recorder killed with SIGKILL leaves readable.

Run: ``.venv/bin/python -m bench.bench_recording`` (about 15 s). For each delay, an
embedded router, a `fleet record` process, and a client putting N small status
messages 2.5 ms apart; the recorder is SIGKILLed the given delay after the last put,
and its file read back (`fleet.recording.reader`). Prints a markdown table: messages
read back of those sent, and the size of the file.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import zenoh

from fleet.launch.endpoints import free_port
from fleet.mission.key_space import DEFAULT_SPACE
from fleet.recording.reader import read_recording
from fleet.transport.router import Router
from fleet.transport.zenoh_config import make_config

PERIOD_S = 0.0025


def kill_after(delay_s: float, count: int, directory: Path) -> tuple[int, int]:
    """(messages read back, file bytes) for a recorder SIGKILLed `delay_s` after the last put."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = directory / f"kill-{delay_s:g}.mcap"
    with Router([endpoint]) as _router, zenoh.open(make_config("client", [endpoint])) as session:
        recorder = subprocess.Popen(
            [sys.executable, "-m", "fleet.recording.commands", "record", str(out),
             "--connect", endpoint, "--state-every", "0"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )  # fmt: skip
        try:
            assert recorder.stdout is not None
            recorder.stdout.readline()  # "fleet record: recording ...": it listens
            for i in range(count):
                session.put(DEFAULT_SPACE.status(1), b'{"text":"%d"}' % i)
                time.sleep(PERIOD_S)
            time.sleep(delay_s)
            os.kill(recorder.pid, signal.SIGKILL)
        finally:
            recorder.kill()
            recorder.wait()
    return len(read_recording(out).messages), out.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=1000)
    args = parser.parse_args()
    print("| killed after the last put | read back | file bytes |")
    print("|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as directory:
        for delay in (0.0, 0.25, 0.6, 1.0):
            got, size = kill_after(delay, args.count, Path(directory))
            print(f"| {delay:g} s | {got} / {args.count} | {size:,} |")


if __name__ == "__main__":
    main()
