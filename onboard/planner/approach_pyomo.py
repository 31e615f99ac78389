"""The approach-time LP as a Pyomo model: the reference the onboard's LP is checked against.

`build_point_mass` states the model of `onboard.planner.approach_model` in Pyomo (the module
docstring there explains it); `PyomoLp` hands it to HiGHS through Pyomo's persistent
interface and changes it by variable bounds only. `ApproachTimeModel(...,
backend=LpBackend.PYOMO)` runs the LP scan on it. The onboard process does not: it builds
the very same LP (same rows, columns, order and coefficients) straight on HiGHS
(`onboard.planner.approach_highs.HighsLp`), without Pyomo or numpy in memory; the tests and
`bench/bench_approach.py` check that both give the same times, and the bench's MILP
reference is built from this model.

Pyomo overheads
---------------
The persistent interface's `solve()` costs ~2-4 ms per call on top of a ~2-3 ms
warm-started LP, and it redirects the process-wide stdout/stderr file descriptors while
HiGHS runs, which would swallow other threads' log output. The model is therefore
translated and updated through the persistent interface (`set_instance`,
`update_variables`) and run on the HiGHS instance that interface owns.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import highspy
import pyomo.environ as pyo
from pyomo.contrib.solver.common.factory import SolverFactory
from pyomo.contrib.solver.common.results import TerminationCondition

from fleet.geo.aircraft import AircraftLimits
from onboard.planner.approach_lp import (
    ACCEL_INRADIUS,
    NORMALS,
    SIDES,
    SPEED_INRADIUS,
    ApproachModelError,
    BoundChange,
    grid_times,
)

__all__ = ["PyomoLp", "build_point_mass"]

logger = logging.getLogger(__name__)


def build_point_mass(limits: AircraftLimits, steps: Sequence[float]) -> pyo.ConcreteModel:
    """The Pyomo point-mass model on the time grid `steps`, in the heading frame.

    Variables x, y, vx, vy on nodes 0..n, ax, ay on steps 0..n-1; node 0 is fixed at the
    origin flying along +x at max speed (change vx[0]'s bounds for another speed, and
    see `along_velocity_bounds`). The selection part (slacks sx, sy, gap vector ex, ey,
    target tx, ty, wind wx, wy and the objective `gap`) serves the LP scan; the bench's MILP
    reference reuses the rest. `onboard.planner.approach_highs.point_mass_lp` is the same LP,
    row for row.
    """
    n = len(steps)
    v_cap = limits.max_airspeed * SPEED_INRADIUS
    a_cap = limits.max_accel * ACCEL_INRADIUS
    m = pyo.ConcreteModel(name="approach_time")
    m.K = pyo.RangeSet(0, n)  # nodes
    m.S = pyo.RangeSet(0, n - 1)  # steps
    m.F = pyo.RangeSet(0, SIDES - 1)  # polygon facets
    m.x = pyo.Var(m.K)
    m.y = pyo.Var(m.K)
    m.vx = pyo.Var(m.K)
    m.vy = pyo.Var(m.K)
    m.ax = pyo.Var(m.S)
    m.ay = pyo.Var(m.S)
    # Slack pair per node: fixed to 0 on the node being tested, free elsewhere.
    m.sx = pyo.Var(m.K)
    m.sy = pyo.Var(m.K)
    m.ex = pyo.Var()  # target minus the tested node's position
    m.ey = pyo.Var()
    m.tx = pyo.Var()  # target, fixed through its bounds
    m.ty = pyo.Var()
    m.wx = pyo.Var()  # wind, fixed through its bounds
    m.wy = pyo.Var()
    times = grid_times(steps)
    m.gap = pyo.Var(bounds=(0.0, None))

    def pos_x(b: Any, k: int) -> Any:
        dt = steps[k]
        return b.x[k + 1] == b.x[k] + dt * b.vx[k] + 0.5 * dt * dt * b.ax[k]

    def pos_y(b: Any, k: int) -> Any:
        dt = steps[k]
        return b.y[k + 1] == b.y[k] + dt * b.vy[k] + 0.5 * dt * dt * b.ay[k]

    def vel_x(b: Any, k: int) -> Any:
        return b.vx[k + 1] == b.vx[k] + steps[k] * b.ax[k]

    def vel_y(b: Any, k: int) -> Any:
        return b.vy[k + 1] == b.vy[k] + steps[k] * b.ay[k]

    def speed(b: Any, k: int, f: int) -> Any:
        nx, ny = NORMALS[f]
        return nx * b.vx[k] + ny * b.vy[k] <= v_cap

    def accel(b: Any, k: int, f: int) -> Any:
        nx, ny = NORMALS[f]
        return nx * b.ax[k] + ny * b.ay[k] <= a_cap

    # The target drifts through the air at minus the wind (`onboard.planner.approach_lp`);
    # node 0 has no drift term, as in the arrays.
    def select_x(b: Any, k: int) -> Any:
        if k == 0:
            return b.ex == b.tx - b.x[k] + b.sx[k]
        return b.ex == b.tx - b.x[k] + b.sx[k] - times[k] * b.wx

    def select_y(b: Any, k: int) -> Any:
        if k == 0:
            return b.ey == b.ty - b.y[k] + b.sy[k]
        return b.ey == b.ty - b.y[k] + b.sy[k] - times[k] * b.wy

    def gauge(b: Any, f: int) -> Any:
        nx, ny = NORMALS[f]
        return b.gap >= nx * b.ex + ny * b.ey

    m.pos_x = pyo.Constraint(m.S, rule=pos_x)
    m.pos_y = pyo.Constraint(m.S, rule=pos_y)
    m.vel_x = pyo.Constraint(m.S, rule=vel_x)
    m.vel_y = pyo.Constraint(m.S, rule=vel_y)
    # Node 0 is fixed by bounds, so its speed needs no polygon.
    m.speed = pyo.Constraint(pyo.RangeSet(1, n), m.F, rule=speed)
    m.accel = pyo.Constraint(m.S, m.F, rule=accel)
    m.select_x = pyo.Constraint(m.K, rule=select_x)
    m.select_y = pyo.Constraint(m.K, rule=select_y)
    m.gauge = pyo.Constraint(m.F, rule=gauge)
    m.objective = pyo.Objective(expr=m.gap, sense=pyo.minimize)

    # The heading frame puts the aircraft at the origin flying along +x.
    for var in (m.x[0], m.y[0], m.vy[0], m.tx, m.ty, m.wx, m.wy):
        var.setlb(0.0)
        var.setub(0.0)
    m.vx[0].setlb(limits.max_airspeed)
    m.vx[0].setub(limits.max_airspeed)
    return m


class PyomoLp:
    """`build_point_mass` on Pyomo's persistent HiGHS interface, run without its
    per-solve overhead (module docstring).

    Model translation and every later bound change go through the public persistent
    API. The run itself uses the HiGHS instance the interface owns; if a future Pyomo
    renames that attribute, this falls back to the public `solve()`, slower but correct.
    """

    def __init__(self, limits: AircraftLimits, steps: Sequence[float]) -> None:
        model = build_point_mass(limits, steps)
        opt: Any = SolverFactory("highs")
        if int(opt.available()) <= 0:
            raise ApproachModelError("HiGHS (highspy) is not available")
        updates = opt.config.auto_updates
        # Only bounds change after construction, and they are pushed explicitly.
        for flag in (
            "check_for_new_or_removed_constraints",
            "check_for_new_or_removed_vars",
            "check_for_new_or_removed_params",
            "check_for_new_objective",
            "update_constraints",
            "update_vars",
            "update_parameters",
            "update_named_expressions",
            "update_objective",
        ):
            setattr(updates, flag, False)
        opt.config.load_solutions = False
        opt.config.raise_exception_on_nonoptimal_result = False
        opt.set_instance(model)
        self.model = model
        self._opt = opt
        #: The HiGHS instance the interface owns; None runs the public `solve()`.
        self.highs: Any = getattr(opt, "_solver_model", None)
        if self.highs is not None:
            self.highs.setOptionValue("output_flag", False)
            # One thread: the machine is shared and these LPs are far too small to gain.
            self.highs.setOptionValue("threads", 1)
        else:
            logger.warning("pyomo highs interface has no _solver_model; using solve()")

    def set_bounds(self, changes: Sequence[BoundChange]) -> None:
        """Set the bounds of the named variables (None: unbounded) and send them to HiGHS."""
        changed = []
        for (name, index), lower, upper in changes:
            component = getattr(self.model, name)
            var = component[index] if component.is_indexed() else component
            var.setlb(lower)
            var.setub(upper)
            changed.append(var)
        if changed:
            self._opt.update_variables(changed)

    def minimise(self) -> float | None:
        """Solve the LP; the optimal objective, or None if it is not optimal."""
        if self.highs is None:
            res = self._opt.solve(self.model)
            ok = res.termination_condition == TerminationCondition.convergenceCriteriaSatisfied
            return float(res.incumbent_objective) if ok else None
        self.highs.run()
        if self.highs.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            # Drop the basis, so that the next LP does not warm-start from a failed one.
            self.highs.clearSolver()
            return None
        return float(self.highs.getInfo().objective_function_value)
