"""What a command costs before it does anything: CPU time of each program's start.

Run: ``.venv/bin/python -m bench.bench_startup [--runs 7]``

Each command runs as a user runs it (``python -m ROOT ARGS``, a new interpreter each
time) and is measured by the CPU time (user + system) its process used, from the
kernel's account of finished children (`resource.getrusage(RUSAGE_CHILDREN)`): on a
loaded box the wall time of a start says more about the neighbours than about the
command, its CPU time does not. The reference, measured in the same run, is a bare
interpreter (``python -c pass``): each figure is also given as a ratio to it.

`ground-cli uavs` asks a router started by this script (in its own process, an
embedded Zenoh router, no UAV): the figure is the command's whole cost, connecting and
querying included. Prints the median of `--runs` runs of each.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from fleet.launch.endpoints import free_port
from fleet.transport.router import Router

REPO = Path(__file__).resolve().parents[1]


def cpu_of(argv: Sequence[str]) -> float:
    """CPU seconds (user + system) the process `argv` used, run to its end."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, *argv], cwd=REPO, capture_output=True, check=False, timeout=120)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def median_cpu(argv: Sequence[str], runs: int) -> float:
    return statistics.median(cpu_of(argv) for _ in range(runs))


def commands(endpoint: str) -> dict[str, list[str]]:
    return {
        "python -c pass (reference)": ["-c", "pass"],
        "ground-cli --help": ["-m", "ground.cli", "--help"],
        "fleet --help": ["-m", "programs.fleet_cli", "--help"],
        "ground-cli uavs": ["-m", "ground.cli", "--connect", endpoint, "uavs"],
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=7, help="runs of each command (median)")
    args = parser.parse_args(argv)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Router([endpoint]):
        figures = {
            name: median_cpu(command, args.runs) for name, command in commands(endpoint).items()
        }
    reference = figures["python -c pass (reference)"]
    print(f"CPU time per start, median of {args.runs} runs")
    for name, cpu in figures.items():
        ratio = f"{cpu / reference:5.1f}x the reference" if reference > 0 else ""
        print(f"  {name:32} {cpu:6.3f} s  {ratio}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
