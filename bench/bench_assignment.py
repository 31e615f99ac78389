"""How far the thesis's greedy assignment is from the optimal one, and what it costs.

Run:  .venv/bin/python -m bench.bench_assignment [--instances N] [--seed S]

For each team shape (N UAVs x M targets) and each of two instance families, draws
seeded random approach-time matrices and compares the total approach time of
`fleet.consensus.assignment.greedy_assign` with the minimum total over all assignments of
min(N, M) pairs (`scipy.optimize.linear_sum_assignment`, which accepts rectangular
matrices). Prints a Markdown table: median and worst greedy/optimal ratio, how often the
greedy is optimal, and the median time per call of each (same run, same machine, so the
scipy figure is the reference, not an absolute).

Families:
* geometric: UAVs and targets uniform in a 20 km square, each UAV with its own speed in
  15-30 m/s; time = straight-line distance / speed (what the approach-time model
  roughly yields, and correlated across UAVs as real results are);
* uniform: i.i.d. times uniform in [10, 600] s (no structure; a harder case for greedy).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from scipy.optimize import linear_sum_assignment

from fleet.consensus.assignment import greedy_assign

Matrix = npt.NDArray[np.float64]
SHAPES: tuple[tuple[int, int], ...] = ((2, 3), (5, 8), (10, 10), (20, 10), (20, 50))
# Piccolo IDs are not 0..N-1 in the field; spreading them keeps the ID tie-break honest.
_ID_STRIDE = 37
_ID_BASE = 11


def geometric(rng: np.random.Generator, n_uavs: int, n_targets: int) -> Matrix:
    uavs = rng.uniform(0.0, 20_000.0, size=(n_uavs, 2))
    targets = rng.uniform(0.0, 20_000.0, size=(n_targets, 2))
    speed = rng.uniform(15.0, 30.0, size=(n_uavs, 1))
    distance = np.linalg.norm(uavs[:, None, :] - targets[None, :, :], axis=2)
    result: Matrix = distance / speed
    return result


def uniform(rng: np.random.Generator, n_uavs: int, n_targets: int) -> Matrix:
    result: Matrix = rng.uniform(10.0, 600.0, size=(n_uavs, n_targets))
    return result


FAMILIES: dict[str, Callable[[np.random.Generator, int, int], Matrix]] = {
    "geometric": geometric,
    "uniform": uniform,
}


def _as_results(matrix: Matrix) -> dict[int, list[float | None]]:
    # The form the onboard module holds: Piccolo ID -> list of Python floats.
    return {
        _ID_BASE + _ID_STRIDE * row: [float(t) for t in matrix[row]]
        for row in range(matrix.shape[0])
    }


def run_shape(
    family: Callable[[np.random.Generator, int, int], Matrix],
    n_uavs: int,
    n_targets: int,
    instances: int,
    seed: int,
) -> dict[str, float]:
    rng = np.random.default_rng([seed, n_uavs, n_targets])
    ratios: list[float] = []
    greedy_ns: list[int] = []
    lsa_ns: list[int] = []
    for _ in range(instances):
        matrix = family(rng, n_uavs, n_targets)
        results = _as_results(matrix)

        t0 = time.perf_counter_ns()
        assignment = greedy_assign(results, n_targets)
        t1 = time.perf_counter_ns()
        rows, cols = linear_sum_assignment(matrix)
        t2 = time.perf_counter_ns()
        greedy_ns.append(t1 - t0)
        lsa_ns.append(t2 - t1)

        ids = sorted(results)
        greedy_total = sum(matrix[ids.index(uav), tgt] for uav, tgt in assignment.pairs.items())
        optimal_total = float(matrix[rows, cols].sum())
        if len(assignment.pairs) != len(rows):
            raise AssertionError("greedy and optimal assigned different numbers of pairs")
        ratios.append(greedy_total / optimal_total)
    return {
        "median": statistics.median(ratios),
        "p95": float(np.percentile(ratios, 95)),
        "worst": max(ratios),
        "optimal_share": sum(r <= 1.0 + 1e-12 for r in ratios) / len(ratios),
        "greedy_us": statistics.median(greedy_ns) / 1000.0,
        "lsa_us": statistics.median(lsa_ns) / 1000.0,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--instances", type=int, default=1000, help="instances per shape")
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args(argv)

    print(f"instances per shape: {args.instances}, seed: {args.seed}")
    print()
    print(
        "| family | UAVs x targets | median ratio | p95 ratio | worst ratio | greedy optimal "
        "| greedy us/call | linear_sum_assignment us/call |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, family in FAMILIES.items():
        for n_uavs, n_targets in SHAPES:
            r = run_shape(family, n_uavs, n_targets, args.instances, args.seed)
            print(
                f"| {name} | {n_uavs} x {n_targets} | {r['median']:.3f} | {r['p95']:.3f} "
                f"| {r['worst']:.3f} | {100.0 * r['optimal_share']:.0f} % "
                f"| {r['greedy_us']:.1f} | {r['lsa_us']:.1f} |"
            )


if __name__ == "__main__":
    main()
