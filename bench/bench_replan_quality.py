"""The remaining plan's quality after a loss: appended, resolved, solved from scratch.

Seeded instances of N UAVs x M targets (UAVs and targets uniform in a square of 2 km per
sqrt(target), every time and leg the straight line at 22 m/s, as `bench_queues`). Per
instance and objective: the epoch-0 plan (`plan_queues`) is flown for a fraction
(`--at`, of its last arrival) of its time, every UAV on its queue in a straight line;
then the UAV with the most targets still to fly is lost. From where the survivors are
at that moment (their fresh approach times to every target), three plans of the targets
not reached yet:

* `append`: today's re-plan (`fleet.consensus.replan.replan`): the survivors keep their
  epoch-0 queues and the lost UAV's go to their ends where reached earliest by the
  epoch-0 times; a reached target is skipped;
* `resolved`: `fleet.consensus.resolve.resolve` on the fresh times, each survivor's
  current target kept first unless the objective gains;
* `scratch`: `plan_queues` on the same fresh times and remaining targets, nobody's
  current target kept: the reference.

Each plan is scored from the moment of the loss with the fresh times (total of arrivals
for min-sum, last arrival for min-max) and printed as a ratio to `scratch` on the same
instance (mean / worst), in how many instances `resolved` kept every current target
(the plan from scratch did not gain), and the median CPU of `resolved` and `scratch`.
The greedy has no measure to gain by: it keeps every current target, scored by the
total of arrivals. A ratio under
1 means that plan beat the from-scratch heuristic on that instance.

    python -m bench.bench_replan_quality [--instances 10] [--sizes 3x8 5x20 10x50] [--at 0.3]
"""

from __future__ import annotations

import argparse
import math
import random
import statistics
import time
from collections.abc import Sequence

from bench.bench_queues import SPEED_MPS, instance, times_and_legs
from fleet.consensus.assignment import results_digest
from fleet.consensus.objectives import plan_queues
from fleet.consensus.queues import QueuePlan, finish
from fleet.consensus.replan import replan
from fleet.consensus.resolve import Standing, resolve
from fleet.mission.messages import AssignmentReport
from fleet.mission.objective import Objective

Point = tuple[float, float]


def flown(
    start: Point, goals: Sequence[Point], queue: Sequence[int], at: float
) -> tuple[Point, int]:
    """Where a UAV flying `queue` from `start` is `at` seconds in, and how many targets of
    it it has reached (done with its queue: it stays at its last target)."""
    where, clock = start, 0.0
    for done, target in enumerate(queue):
        leg = math.dist(where, goals[target]) / SPEED_MPS
        if clock + leg > at:
            share = (at - clock) / leg if leg > 0 else 1.0
            goal = goals[target]
            return (
                where[0] + share * (goal[0] - where[0]),
                where[1] + share * (goal[1] - where[1]),
            ), done
        where, clock = goals[target], clock + leg
    return where, len(queue)


def score(plan: QueuePlan, objective: Objective) -> float:
    return plan.makespan() if objective is Objective.MIN_MAX else plan.total()


def one(
    rng: random.Random, uavs: int, targets: int, objective: Objective, at: float
) -> tuple[float, float, bool, float, float]:
    """(append / scratch, resolved / scratch, every current target kept, resolved CPU s,
    scratch CPU s) of an instance."""
    where, goals, _ = instance(rng, uavs, targets)
    times, legs = times_and_legs(where, goals)
    first = plan_queues(times, legs, objective)
    moment = at * first.makespan()
    standing: dict[int, tuple[Point, int]] = {
        uav: flown(where[i], goals, first.queues[uav], moment)
        for i, uav in enumerate(sorted(times))
    }
    reached = frozenset(t for uav, (_, done) in standing.items() for t in first.queues[uav][:done])
    lost = max(sorted(times), key=lambda u: len(first.queues[u]) - standing[u][1])
    survivors = [uav for uav in sorted(times) if uav != lost]
    fresh = {
        uav: tuple(math.dist(standing[uav][0], g) / SPEED_MPS for g in goals) for uav in survivors
    }
    left = tuple(t for t in range(targets) if t not in reached)
    rows = {uav: tuple(fresh[uav][t] for t in left) for uav in survivors}
    sub = [[legs[i][j] for j in left] for i in left]

    def scored(queues: dict[int, tuple[int, ...]]) -> float:
        position = {t: i for i, t in enumerate(left)}
        renumbered = {u: [position[t] for t in q if t in position] for u, q in queues.items()}
        return score(finish(renumbered, rows, sub), objective)

    base = AssignmentReport(
        mission=1,
        uav=survivors[0],
        target=None,
        pairs=first.heads(),
        unassigned=first.unassigned,
        team=tuple(sorted(times)),
        digest=results_digest(times),
        queues={u: q for u, q in first.queues.items() if q},
        arrivals={u: a for u, a in first.arrivals.items() if a},
        objective=objective,
    )
    appended = replan(base, times, {lost}, legs).plan.queues
    standings = {
        uav: Standing(
            fresh[uav],
            first.queues[uav][standing[uav][1]]
            if standing[uav][1] < len(first.queues[uav])
            else None,
            reached,
        )
        for uav in survivors
    }
    started = time.process_time()
    solved = resolve(standings, left, legs, objective)
    resolved = solved.plan.queues
    resolved_s = time.process_time() - started
    started = time.process_time()
    scratch_plan = plan_queues(rows, sub, objective)
    scratch_s = time.process_time() - started
    scratch = score(scratch_plan, objective)
    return (
        scored(appended) / scratch,
        scored(resolved) / scratch,
        solved.kept,
        resolved_s,
        scratch_s,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", type=int, default=10)
    parser.add_argument("--sizes", nargs="+", default=["3x8", "5x20", "10x50"])
    parser.add_argument("--at", type=float, default=0.3, help="the loss, as a share of the plan")
    parser.add_argument("--seed", type=int, default=34)
    args = parser.parse_args()
    print(f"{args.instances} instances a size; one UAV lost at {args.at:g} of the plan's time")
    print("| size | objective | append / scratch mean / worst | resolved / scratch mean / worst "
          "| current targets kept | resolved CPU | scratch CPU |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for size in args.sizes:
        uavs, targets = map(int, size.split("x"))
        for objective in (Objective.GREEDY, Objective.MIN_SUM, Objective.MIN_MAX):
            appended: list[float] = []
            resolved: list[float] = []
            kept = 0
            cpu: dict[str, list[float]] = {"resolved": [], "scratch": []}
            for k in range(args.instances):
                rng = random.Random(f"{args.seed}:{size}:{k}")
                a, r, k, r_s, s_s = one(rng, uavs, targets, objective, args.at)
                appended.append(a)
                resolved.append(r)
                kept += k
                cpu["resolved"].append(r_s)
                cpu["scratch"].append(s_s)
            print(
                f"| {size} | {objective.value} "
                f"| {statistics.mean(appended):.3f} / {max(appended):.3f} "
                f"| {statistics.mean(resolved):.3f} / {max(resolved):.3f} "
                f"| {kept} of {args.instances} "
                f"| {1000 * statistics.median(cpu['resolved']):.0f} ms "
                f"| {1000 * statistics.median(cpu['scratch']):.0f} ms |"
            )


if __name__ == "__main__":
    main()
