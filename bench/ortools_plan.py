"""OR-Tools' routing solver as a reference for the plan-quality bench (`pip install
'.[compare]'`): not a proposer (a time limit makes its plan depend on the machine's
speed), only a second state-of-the-art opinion of the best known plan.

The queue problem as OR-Tools' open vehicle routing: each UAV's own start node (its
approach time to each target), a shared end node reached from anywhere for free, each
UAV's arcs timed in its own table (centiseconds, OR-Tools' costs are integers), a time
dimension whose cumul at a target is its arrival.

* `min-max`: the travel as arc cost plus the dimension's global span (the last arrival)
  at a weight of 100: the usual min-max formulation;
* `min-sum`: every target's arrival as a soft upper bound of 0 at a cost of 10 a unit
  (the sum of arrivals) plus the travel as arc cost (the first solution needs one).

First solution by parallel cheapest insertion, then guided local search for `seconds`
(wall time). Every plan is re-scored by the project's own scorer by the bench.
"""

from __future__ import annotations

import math

from fleet.consensus.queues import Legs, Queues, Times, leg_count, legs_of
from fleet.mission.objective import Objective
from fleet.solver.pyvrp_plan import finite_time, time_units

#: What an arc no UAV may fly costs (it is also removed from the vehicle's choices).
FORBIDDEN = 10**9


def solve_ortools(times: Times, legs: Legs, objective: Objective, seconds: float) -> Queues:
    """Every UAV's queue by OR-Tools for `objective`, searched for `seconds`."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    uavs = sorted(times)
    count = leg_count(legs)
    clients = [t for t in range(count) if any(finite_time(times[u][t]) for u in uavs)]
    if not clients:
        return {uav: [] for uav in uavs}
    end = len(uavs)
    nodes = end + 1 + len(clients)
    manager = pywrapcp.RoutingIndexManager(nodes, len(uavs), list(range(end)), [end] * end)
    routing = pywrapcp.RoutingModel(manager)

    def matrix(k: int) -> list[list[int]]:
        row, table = times[uavs[k]], legs_of(legs, uavs[k])
        out = [[0] * nodes for _ in range(nodes)]
        for c, t in enumerate(clients):
            a = end + 1 + c
            out[k][a] = time_units(row[t]) if finite_time(row[t]) else FORBIDDEN
            for c2, t2 in enumerate(clients):
                if c2 != c:
                    leg = table[t][t2]
                    out[a][end + 1 + c2] = time_units(leg) if math.isfinite(leg) else FORBIDDEN
        return out

    # Matrices, not Python callbacks: the search then runs in C++ alone.
    callbacks = [routing.RegisterTransitMatrix(matrix(k)) for k in range(len(uavs))]
    for k, callback in enumerate(callbacks):
        routing.SetArcCostEvaluatorOfVehicle(callback, k)
    routing.AddDimensionWithVehicleTransits(callbacks, 0, FORBIDDEN, True, "time")
    dimension = routing.GetDimensionOrDie("time")
    for c, t in enumerate(clients):
        index = manager.NodeToIndex(end + 1 + c)
        barred = [k for k, uav in enumerate(uavs) if not finite_time(times[uav][t])]
        if barred:
            routing.VehicleVar(index).RemoveValues(barred)
        if objective is Objective.MIN_SUM:
            dimension.SetCumulVarSoftUpperBound(index, 0, 10)
    if objective is Objective.MIN_MAX:
        dimension.SetGlobalSpanCostCoefficient(100)
    parameters = pywrapcp.DefaultRoutingSearchParameters()
    parameters.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION
    )
    parameters.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    )
    parameters.time_limit.FromMilliseconds(max(1, round(1000 * seconds)))
    solution = routing.SolveWithParameters(parameters)
    queues: Queues = {uav: [] for uav in uavs}
    if solution is None:
        return queues
    for k, uav in enumerate(uavs):
        index = solution.Value(routing.NextVar(routing.Start(k)))
        while not routing.IsEnd(index):
            queues[uav].append(clients[manager.IndexToNode(index) - end - 1])
            index = solution.Value(routing.NextVar(index))
    return queues
