"""Plan quality against PyVRP and OR-Tools: the baseline every UAV computes, the proposed
plan, the plan adopted, for min-sum and min-max.

Seeded instances of N UAVs x M targets (3x8, 5x20, 10x50, 20x100; UAVs and targets
uniform in a square of 2 km per sqrt(target), as `bench_queues`), every approach time
and leg the straight line at 22 m/s (one table for every UAV), every plan scored by
the project's own scorer (`finish`: total of arrivals for min-sum, last arrival for
min-max). Per size and objective, each method's measure as a ratio to the best known
(the best any method found on that instance; mean and worst over the instances):

* `baseline`: `plan_queues`, what every UAV computes;
* `pyvrp`: `fleet.solver.pyvrp_plan.solve_queues` (PyVRP, fixed seed, `--iterations`;
  min-max by bisection on the route duration, min-sum PyVRP then the project's search),
  the ground's proposal;
* `adopted`: the better of the two by the deterministic scorer (what the team adopts
  when the ground proposes), so never worse than the baseline;
* `ortools`: OR-Tools' routing solver (`bench.ortools_plan`, guided local search for
  `--ortools-seconds` a solve), a reference only, never proposed; left out (with a
  note) where OR-Tools is not installed;

and the CPU of each (median per instance). Needs `pip install '.[solver]'` and, for the
reference, `pip install '.[compare]'`.

    python -m bench.bench_plan_quality [--instances 10] [--sizes 3x8 5x20 10x50 20x100]
        [--objectives min-sum min-max]
"""

from __future__ import annotations

import argparse
import importlib.util
import random
import statistics
import time
from collections.abc import Callable

from bench.bench_queues import Legs, Times, instance, times_and_legs
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import Queues, finish
from fleet.mission.objective import Objective
from fleet.solver.pyvrp_plan import solve_queues


def _timed(solve: Callable[[], Queues]) -> tuple[Queues, float]:
    started = time.process_time()
    queues = solve()
    return queues, time.process_time() - started


def _baseline(times: Times, legs: Legs, objective: Objective) -> Queues:
    return {u: list(q) for u, q in plan_queues(times, legs, objective).queues.items()}


def _run(
    times: Times, legs: Legs, objective: Objective, args: argparse.Namespace, with_ortools: bool
) -> tuple[dict[str, float], dict[str, float]]:
    """Each method's measure on one instance, and each solver's CPU (s)."""

    def score(queues: Queues) -> float:
        plan = finish(queues, times, legs)
        return plan.makespan() if objective is Objective.MIN_MAX else plan.total()

    solvers: dict[str, Callable[[], Queues]] = {
        "baseline": lambda: _baseline(times, legs, objective),
        "pyvrp": lambda: solve_queues(times, legs, objective, iterations=args.iterations),
    }
    if with_ortools:
        from bench.ortools_plan import solve_ortools

        solvers["ortools"] = lambda: solve_ortools(times, legs, objective, args.ortools_seconds)
    plans: dict[str, Queues] = {}
    seconds: dict[str, float] = {}
    for name, solve in solvers.items():
        plans[name], seconds[name] = _timed(solve)
    plans["adopted"] = min(plans["baseline"], plans["pyvrp"], key=score)
    return {name: score(plan) for name, plan in plans.items()}, seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", type=int, default=10)
    parser.add_argument("--sizes", nargs="+", default=["3x8", "5x20", "10x50", "20x100"])
    parser.add_argument("--iterations", type=int, default=1500)
    parser.add_argument("--ortools-seconds", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=35)
    parser.add_argument(
        "--objectives",
        nargs="+",
        type=Objective,
        default=[Objective.MIN_SUM, Objective.MIN_MAX],
        help="min-sum and/or min-max (default both)",
    )
    args = parser.parse_args()
    with_ortools = importlib.util.find_spec("ortools") is not None
    names = ["baseline", "pyvrp", "adopted"] + (["ortools"] if with_ortools else [])
    print(
        f"{args.instances} instances a size; PyVRP {args.iterations} iterations, seed 1; "
        + (
            f"OR-Tools {args.ortools_seconds} s a solve"
            if with_ortools
            else "OR-Tools not installed (pip install '.[compare]'): not run"
        )
    )
    print(
        "| size | objective | "
        + " | ".join(f"{n} mean / worst" for n in names)
        + " | "
        + " | ".join(f"{n} CPU" for n in names if n != "adopted")
        + " |"
    )
    print("|---" * (2 + 2 * len(names) - 1) + "|")
    for size in args.sizes:
        uavs, targets = map(int, size.split("x"))
        for objective in args.objectives:
            ratios: dict[str, list[float]] = {n: [] for n in names}
            cpu: dict[str, list[float]] = {n: [] for n in names if n != "adopted"}
            for k in range(args.instances):
                rng = random.Random(f"{args.seed}:{size}:{k}")
                where, goals, _ = instance(rng, uavs, targets)
                times, legs = times_and_legs(where, goals)

                values, seconds = _run(times, legs, objective, args, with_ortools)
                for name, value in seconds.items():
                    cpu[name].append(value)
                best = min(values.values())
                for n in names:
                    ratios[n].append(values[n] / best)
            cells = [f"{statistics.mean(r):.3f} / {max(r):.3f}" for r in ratios.values()]
            times_cells = [_cpu(statistics.median(c)) for c in cpu.values()]
            print(f"| {size} | {objective.value} | {' | '.join(cells + times_cells)} |")


def _cpu(seconds: float) -> str:
    return f"{1000 * seconds:.0f} ms" if seconds < 1.0 else f"{seconds:.1f} s"


if __name__ == "__main__":
    main()
