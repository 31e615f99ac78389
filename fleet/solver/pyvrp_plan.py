"""A plan proposed by a state-of-the-art routing solver: PyVRP (`pip install '.[solver]'`).

The queue problem is an open multi-vehicle routing problem: each UAV starts where it is
(its approach time to each target, from its result), flies its queue, and ends at its
last target. PyVRP minimises the travel; the two objectives are reached thus:

* `min-max`: a bisection on a bound of each route's duration (`max_distance`): the least
  bound under which PyVRP still serves every target, the plan of that bound;
* `min-sum`: PyVRP's least-travel plan, then the project's own local search for the sum
  of arrivals (`fleet.consensus.improve`), which PyVRP has no objective for, then an
  iterated local search on that sum (`fleet.solver.min_sum_search`).

Deterministic for a seed and an iteration limit (`MaxIterations`: a time limit would
make the plan depend on the machine's speed), on one machine and build; nothing more
is promised, which is why a plan solved here is only *proposed*: every UAV re-scores
it with the deterministic scorer (`fleet.consensus.proposal`). Times are solved in
centiseconds (PyVRP's matrices are integers). Each UAV's own legs are its own profile.
"""

from __future__ import annotations

import importlib.util
import itertools
import math
import warnings
from collections.abc import Sequence
from typing import Any

from fleet.consensus.improve import improve
from fleet.consensus.queues import Legs, Queues, Times, leg_count, legs_of
from fleet.errors import FleetError
from fleet.mission.objective import Objective
from fleet.solver.min_sum_search import search_min_sum

__all__ = ["SolverUnavailable", "solve_queues", "solver_available"]

#: The solver's unit: seconds x SCALE are its integers.
SCALE = 100
#: What a forbidden edge costs (PyVRP's own default for a missing one is 2^44).
FORBIDDEN = 1 << 40
#: Iterations of PyVRP per solve, and bisection steps for min-max.
ITERATIONS = 1500
BISECTION_STEPS = 12


class SolverUnavailable(FleetError, RuntimeError):
    """PyVRP is not installed: `pip install '.[solver]'`."""


def solver_available() -> bool:
    """Whether PyVRP can be imported here (found, not imported: it loads in seconds)."""
    return importlib.util.find_spec("pyvrp") is not None


def solve_queues(
    times: Times,
    legs: Legs,
    objective: Objective,
    *,
    seed: int = 1,
    iterations: int = ITERATIONS,
) -> Queues:
    """Every UAV's queue, solved by PyVRP for `objective` (min-sum or min-max)."""
    try:
        import numpy as np
        import pyvrp
        from pyvrp.stop import MaxIterations
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise SolverUnavailable("PyVRP is not installed: pip install '.[solver]'") from exc
    uavs = sorted(times)
    count = leg_count(legs)
    # Only targets some UAV reaches are clients; they are served by reachers only.
    clients = [t for t in range(count) if any(finite_time(times[u][t]) for u in uavs)]
    if not clients or not uavs:
        return {uav: [] for uav in uavs}
    size = len(uavs) + 1 + len(clients)  # start depots, the end depot, the clients
    end = len(uavs)
    matrices: list[Any] = []
    for profile, uav in enumerate(uavs):
        matrix = np.full((size, size), FORBIDDEN, dtype=np.int64)
        np.fill_diagonal(matrix, 0)
        row = times[uav]
        table = legs_of(legs, uav)
        matrix[profile, end] = 0
        for c, t in enumerate(clients):
            at = end + 1 + c
            matrix[at, end] = 0
            if finite_time(row[t]):
                matrix[profile, at] = time_units(row[t])
            from_t = table[t]
            for c2, t2 in enumerate(clients):
                if c2 != c and math.isfinite(from_t[t2]):
                    matrix[at, end + 1 + c2] = time_units(from_t[t2])
        matrices.append(matrix)
    locations = [pyvrp.Location(0.0, 0.0) for _ in range(size)]
    depots = [pyvrp.Depot(location=i) for i in range(len(uavs) + 1)]
    client_data = [pyvrp.Client(location=end + 1 + c) for c in range(len(clients))]

    def solve(bound: int) -> list[list[int]] | None:
        vehicle_types = [
            pyvrp.VehicleType(
                num_available=1,
                start_depot=profile,
                end_depot=end,
                max_distance=bound,
                profile=profile,
            )
            for profile in range(len(uavs))
        ]
        data = pyvrp.ProblemData(
            locations, client_data, depots, vehicle_types, matrices, [m * 0 for m in matrices]
        )
        with warnings.catch_warnings():
            # A bound too tight is infeasible: PyVRP says so in a warning, the plan too.
            warnings.simplefilter("ignore")
            result = pyvrp.solve(data, MaxIterations(iterations), seed=seed, display=False)
        best = result.best
        if not best.is_feasible() or not best.is_complete():
            return None
        routes: list[list[int]] = [[] for _ in uavs]
        for route in best.routes():
            routes[route.vehicle_type()] = [clients[a.idx] for a in route if a.is_client()]
        return routes

    unbounded = solve(FORBIDDEN - 1)
    if unbounded is None:
        return {uav: [] for uav in uavs}  # pragma: no cover - every client has a reacher
    best = unbounded
    if objective is Objective.MIN_MAX:
        high = max(_route_units(times, legs, uavs[p], r) for p, r in enumerate(best))
        low = max(
            min(time_units(times[u][t]) for u in uavs if finite_time(times[u][t])) for t in clients
        )
        for _ in range(BISECTION_STEPS):
            if high - low <= 1:
                break
            middle = (low + high) // 2
            routes = solve(middle)
            if routes is None:
                low = middle
            else:
                best = routes
                high = max(_route_units(times, legs, uavs[p], r) for p, r in enumerate(routes))
    queues = {uav: list(route) for uav, route in zip(uavs, best, strict=True)}
    if objective is Objective.MIN_SUM:
        queues = improve(queues, times, legs, Objective.MIN_SUM)
        queues = search_min_sum(queues, times, legs, seed=seed)
    return queues


def finite_time(time: float | None) -> bool:
    """Whether `time` is an approach or leg time a solver can be given."""
    return time is not None and math.isfinite(time)


def time_units(seconds: float | None) -> int:
    """`seconds` in the solvers' integer unit (SCALE)."""
    assert seconds is not None
    return round(seconds * SCALE)


def _route_units(times: Times, legs: Legs, uav: int, route: Sequence[int]) -> int:
    if not route:
        return 0
    table = legs_of(legs, uav)
    total = time_units(times[uav][route[0]])
    for a, b in itertools.pairwise(route):
        total += time_units(table[a][b])
    return total
