"""Plan quality against PyVRP: the baseline every UAV computes, the proposed plan, the
plan adopted, for min-sum and min-max.

Seeded instances of N UAVs x M targets (3x8, 5x20, 10x50, 20x100; UAVs and targets
uniform in a square of 2 km per sqrt(target), as `bench_queues`), every approach time
and leg the straight line at 22 m/s (one table for every UAV), every plan scored by
the project's own `arrivals_of` (total of arrivals for min-sum, last arrival for
min-max). Per size and objective, each method's measure as a ratio to the best any
method found on that instance (mean and worst over the instances):

* `baseline`: `plan_queues`, what every UAV computes;
* `pyvrp`: `ground.solver_plan.solve_queues` (PyVRP, fixed seed, `--iterations`;
  min-max by bisection on the route duration, min-sum PyVRP then the project's search);
* `adopted`: the better of the two by the deterministic scorer (what the team adopts
  when the ground proposes), so never worse than the baseline;

and the CPU of each (median per instance). Needs `pip install '.[solver]'`.

    python -m bench.bench_plan_quality [--instances 10] [--sizes 3x8 5x20 10x50 20x100]
"""

from __future__ import annotations

import argparse
import random
import statistics
import time
from collections.abc import Callable

from bench.bench_queues import Legs, Times, instance, times_and_legs
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import Queues, finish
from fleet.mission.objective import Objective
from ground.solver_plan import solve_queues


def _methods(
    times: Times, legs: Legs, objective: Objective, iterations: int
) -> tuple[tuple[Queues, float], tuple[Queues, float], Callable[[Queues], tuple[float, float]]]:
    """(baseline, its CPU s), (PyVRP's, its CPU s), the scorer of the objective."""

    def score(queues: Queues) -> tuple[float, float]:
        plan = finish(queues, times, legs)
        if objective is Objective.MIN_MAX:
            return plan.makespan(), plan.total()
        return plan.total(), plan.makespan()

    started = time.process_time()
    base = {u: list(q) for u, q in plan_queues(times, legs, objective).queues.items()}
    base_s = time.process_time() - started
    started = time.process_time()
    solved = solve_queues(times, legs, objective, iterations=iterations)
    solved_s = time.process_time() - started
    return (base, base_s), (solved, solved_s), score


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", type=int, default=10)
    parser.add_argument("--sizes", nargs="+", default=["3x8", "5x20", "10x50", "20x100"])
    parser.add_argument("--iterations", type=int, default=1500)
    parser.add_argument("--seed", type=int, default=35)
    args = parser.parse_args()
    print(f"{args.instances} instances a size; PyVRP {args.iterations} iterations, seed 1")
    print("| size | objective | baseline mean / worst | pyvrp mean / worst "
          "| adopted mean / worst | baseline CPU | pyvrp CPU |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for size in args.sizes:
        uavs, targets = map(int, size.split("x"))
        for objective in (Objective.MIN_SUM, Objective.MIN_MAX):
            ratios: dict[str, list[float]] = {"baseline": [], "pyvrp": [], "adopted": []}
            cpu: dict[str, list[float]] = {"baseline": [], "pyvrp": []}
            for k in range(args.instances):
                rng = random.Random(f"{args.seed}:{size}:{k}")
                where, goals, _ = instance(rng, uavs, targets)
                times, legs = times_and_legs(where, goals)

                (base, base_s), (solved, solved_s), score = _methods(
                    times, legs, objective, args.iterations
                )
                adopted = min(base, solved, key=score)
                values = {"baseline": score(base)[0], "pyvrp": score(solved)[0],
                          "adopted": score(adopted)[0]}  # fmt: skip
                best = min(values.values())
                for name, value in values.items():
                    ratios[name].append(value / best)
                cpu["baseline"].append(base_s)
                cpu["pyvrp"].append(solved_s)
            cells = [f"{statistics.mean(r):.3f} / {max(r):.3f}" for r in ratios.values()]
            print(
                f"| {size} | {objective.value} | {' | '.join(cells)} | "
                f"{1000 * statistics.median(cpu['baseline']):.0f} ms | "
                f"{statistics.median(cpu['pyvrp']):.1f} s |"
            )


if __name__ == "__main__":
    main()
