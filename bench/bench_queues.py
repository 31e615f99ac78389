"""Task queues: how good each objective's plan is, and what the rule costs.

Run:  .venv/bin/python -m bench.bench_queues [--seed S] [--cbba DIR]

Seeded random instances of N UAVs x M targets (2x5, 3x8, 5x20, 10x50, 50x200): UAVs and
targets uniform in a square whose side grows with sqrt(M) (2 km per sqrt(target)), one
airspeed (22 m/s); a UAV's approach time and every leg are straight-line distance over
that speed, so the plan's times are exact for the instance and a reference solver sees
the same problem. For each objective (`fleet.consensus.objectives.plan_queues`) it prints:

* the plan's total of arrival times and last arrival, each as a ratio to the exact
  optimum of that measure (`tests.support.queue_optimum`, a dynamic program over subsets,
  run where it is cheap: 2x5 and 3x8), mean and worst over the instances;
* the same two measures as a ratio to a CBBA plan (Choi, Brunet, How 2009), when
  `--cbba DIR` names a directory holding `CBBA.py` of the public implementation
  keep9oing/consensus-based-bundle-algorithm (fetched and run from outside this repo; its
  code is not part of the project). CBBA maximises a time-discounted reward, sum of
  exp(-arrival distance): it is run on the instance's positions scaled by the square's
  side, fully connected, to convergence, and its paths are scored by the same measures;
* the median time of one call of the rule: every UAV runs it once per decision, so at
  50x200 this is the time per UAV (target: under 100 ms), besides the legs table
  (`leg_times`, once per mission) timed on its own.
"""

from __future__ import annotations

import argparse
import importlib
import math
import random
import statistics
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from fleet.consensus.legs import leg_times
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import QueuePlan, arrivals_of
from fleet.mission.messages import Target
from fleet.mission.objective import Objective
from tests.support.queue_optimum import optimum

SHAPES: tuple[tuple[int, int, int], ...] = (  # UAVs, targets, instances
    (2, 5, 20),
    (3, 8, 20),
    (5, 20, 10),
    (10, 50, 5),
    (50, 200, 3),
)
SPEED_MPS = 22.0
#: Exact optimum by dynamic programming up to this many targets.
EXACT_UP_TO = 8
#: CBBA (the reference's pure Python and numpy take ~5 s at 5 x 20) up to this many
#: targets by default (--cbba-up-to).
CBBA_UP_TO = 20

Times = dict[int, list[float | None]]
Legs = list[list[float]]


def instance(
    rng: random.Random, uavs: int, targets: int
) -> tuple[list[tuple[float, float]], list[tuple[float, float]], float]:
    side = 2000.0 * math.sqrt(targets)
    where = [(rng.uniform(0, side), rng.uniform(0, side)) for _ in range(uavs)]
    goals = [(rng.uniform(0, side), rng.uniform(0, side)) for _ in range(targets)]
    return where, goals, side


def times_and_legs(
    where: Sequence[tuple[float, float]], goals: Sequence[tuple[float, float]]
) -> tuple[Times, Legs]:
    times: Times = {
        101 + i: [math.dist(u, g) / SPEED_MPS for g in goals] for i, u in enumerate(where)
    }
    legs = [[math.dist(a, b) / SPEED_MPS for b in goals] for a in goals]
    return times, legs


def measures(times: Times, legs: Legs, queues: Mapping[int, Sequence[int]]) -> tuple[float, float]:
    """(total of arrivals, last arrival) of these queues."""
    arrivals = [arrivals_of(times[uav], legs, q) for uav, q in queues.items()]
    total = math.fsum(t for row in arrivals for t in row)
    return total, max((row[-1] for row in arrivals if row), default=0.0)


def run_cbba(
    cbba: ModuleType,
    where: Sequence[tuple[float, float]],
    goals: Sequence[tuple[float, float]],
    side: float,
) -> tuple[dict[int, list[int]], float]:
    """CBBA's paths (UAV -> targets in order) and its wall time, fully connected."""
    import numpy as np

    tasks = np.array(goals) / side
    agents = [
        cbba.CBBA_agent(id=i, task_num=len(goals), agent_num=len(where), L_t=len(goals))
        for i in range(len(where))
    ]
    for agent, position in zip(agents, where, strict=True):
        agent.set_state(np.array([position]) / side)
    started = time.perf_counter()
    for _ in range(10 * len(goals) + 10):  # bounded: converges long before
        for agent in agents:
            agent.build_bundle(tasks)
        pool = [agent.send_message() for agent in agents]
        converged = []
        for i, agent in enumerate(agents):
            agent.receive_message({k: pool[k] for k in range(len(agents)) if k != i})
            converged.append(agent.update_task())
        if all(converged):
            break
    elapsed = time.perf_counter() - started
    return {101 + i: [int(t) for t in agent.p] for i, agent in enumerate(agents)}, elapsed


def _planner(times: Times, legs: Legs, objective: Objective) -> Callable[[], QueuePlan]:
    return lambda: plan_queues(times, legs, objective)


def _timed(call: Callable[[], Any], repeat: int) -> tuple[Any, float]:
    best: list[float] = []
    result = None
    for _ in range(repeat):
        started = time.perf_counter()
        result = call()
        best.append(time.perf_counter() - started)
    return result, statistics.median(best)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--cbba", type=Path, help="a directory holding the fetched CBBA.py")
    parser.add_argument("--cbba-up-to", type=int, default=CBBA_UP_TO, metavar="TARGETS")
    parser.add_argument("--instances", type=int, help="instances per shape (default: the table's)")
    parser.add_argument(
        "--shapes", default=",".join(f"{u}x{t}" for u, t, _ in SHAPES), help="e.g. 2x5,3x8"
    )
    args = parser.parse_args(argv)
    cbba: ModuleType | None = None
    if args.cbba is not None:
        sys.path.insert(0, str(args.cbba))
        cbba = importlib.import_module("CBBA")
    rng = random.Random(args.seed)
    print(
        "| UAVs x targets | objective | total / optimal (mean, worst) | last / optimal "
        "(mean, worst) | total / CBBA (mean) | last / CBBA (mean) | rule ms (median) |"
    )
    print("|---|---|---|---|---|---|---|")
    wanted = set(args.shapes.split(","))
    for uavs, count, instances in SHAPES:
        if f"{uavs}x{count}" not in wanted:
            continue
        cases = [instance(rng, uavs, count) for _ in range(args.instances or instances)]
        built = [times_and_legs(w, g) for w, g, _ in cases]
        exact = count <= EXACT_UP_TO
        best = [
            (optimum(t, g, Objective.MIN_SUM), optimum(t, g, Objective.MIN_MAX)) if exact else None
            for t, g in built
        ]
        reference: list[tuple[float, float]] = []
        cbba_s: list[float] = []
        if cbba is not None and count <= args.cbba_up_to:
            for (w, g, side), (t, legs) in zip(cases, built, strict=True):
                paths, elapsed = run_cbba(cbba, w, g, side)
                reference.append(measures(t, legs, paths))
                cbba_s.append(elapsed)
        for objective in Objective:
            ratios_sum: list[float] = []
            ratios_max: list[float] = []
            cbba_sum: list[float] = []
            cbba_max: list[float] = []
            spent: list[float] = []
            for index, (times, legs) in enumerate(built):
                plan: QueuePlan
                plan, seconds = _timed(_planner(times, legs, objective), 3)
                spent.append(seconds)
                total, last = plan.total(), plan.makespan()
                if (opt := best[index]) is not None:
                    ratios_sum.append(total / opt[0])
                    ratios_max.append(last / opt[1])
                if reference:
                    cbba_sum.append(total / reference[index][0])
                    cbba_max.append(last / reference[index][1])

            def pair(values: list[float]) -> str:
                return f"{statistics.fmean(values):.3f}, {max(values):.3f}" if values else "-"

            def mean(values: list[float]) -> str:
                return f"{statistics.fmean(values):.3f}" if values else "-"

            print(
                f"| {uavs} x {count} | {objective} | {pair(ratios_sum)} | {pair(ratios_max)} | "
                f"{mean(cbba_sum)} | {mean(cbba_max)} | {statistics.median(spent) * 1000:.1f} |"
            )
        if cbba_s:
            cbba_ms = statistics.median(cbba_s) * 1000
            print(f"|  | (CBBA wall time, median) |  |  |  |  | {cbba_ms:.0f} |")
    targets = [Target(35.72 + 0.0002 * i, -120.765 + 0.0003 * (i % 17), 600.0) for i in range(200)]
    _, seconds = _timed(lambda: leg_times(targets), 5)
    print(f"\nleg_times for 200 targets (once per mission): {seconds * 1000:.1f} ms")


if __name__ == "__main__":
    main()
