"""The planner: approach times to a mission's targets, computed in a worker thread.

The approach-time model (`approach_model`, its LP on HiGHS in `approach_highs`, the
Pyomo reference in `approach_pyomo`, the shared LP shape in `approach_lp`), the worker
that runs it beside the link loop (`planner_worker`), the routes around no-fly zones
(`route_plan`) and the smoothed wind it plans in (`wind_estimate`). The rest of the
onboard asks it through `PlannerWorker.run` / `result`, nothing else.
"""
