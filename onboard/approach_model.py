"""Minimum approach time from one UAV to each of a set of targets (Richards-How model).

One Pyomo model per UAV is built once, handed to HiGHS once through Pyomo's persistent
interface, and re-solved as the aircraft's state and the targets change by updating
variable bounds only. No constraint is added, removed or rewritten after construction.

Model (all in the aircraft's heading frame, see below)
------------------------------------------------------
A point mass, double integrator in x/y metres, with piecewise-constant acceleration on
a variable time grid (1 s steps for the first 20 s, where turning happens, then steps
that grow to 20 s so that a 600 s horizon fits in ~75 steps). Speed at every node and
acceleration in every step are held inside 16-gons: max airspeed, and
a_max = g tan(bank_limit), the lateral acceleration of a coordinated turn at the bank
limit. Both 16-gons are inscribed in their circles with a vertex dead ahead, so the
point mass is never faster than the aircraft and flies straight ahead at exactly
max speed.

"LP scan" instead of arrival binaries
-------------------------------------
Richards and How minimise the arrival step with one binary per step. Here the same
model has no binaries: for a candidate step k one LP minimises D, the 16-gon distance
from the node-k position to the target. D = 0 means "can be on the target at step k";
the first such k is exactly the MILP optimum. D > 0 also proves a lower bound: velocity
stays inside the speed 16-gon, so any trajectory on the target at t' was within
c * v_max * (t' - t_k) of it at t_k (c = cos(pi/16), the 16-gon's inradius), hence
t' >= t_k + D / (c v_max). The scan jumps straight to the first step past that bound
instead of trying every step, so it costs 1-3 LPs per target. The candidate step is
chosen by the bounds of one slack pair per node (fixed at 0 on the selected node, free
elsewhere), which keeps every change a bound change.

Arrival time inside the step: the best lower bound collected by the scan (at least
t_{k-1}, at most t_k). It is the exact continuous arrival time when the final leg is a
straight line at max speed, which is how the aircraft ends every approach, and it
removes the bias of rounding up to the grid (up to one long step, i.e. 10-20 %).

Why the heading frame, and the turn-rate linearisation
------------------------------------------------------
A free point mass brakes and reverses in a few seconds, whereas the aircraft flies at
constant airspeed and turns at rate w = a_max / v. Measured against a flown
bank-limited reference over all bearings, the pure point mass is up to ~30 %
optimistic for targets behind the aircraft. The aircraft's heading after t seconds
differs from its initial heading by at most theta(t) = w t, so its velocity lies on an
arc of half-angle theta(t); the convex hull of that arc is the circular segment
{|v| <= V, v . h0 >= V cos(theta)}. The model therefore bounds the along-heading
velocity component from below: vx_k >= V cos(w t_k) while w t_k < pi. In the heading
frame (x along the current velocity) that is a variable bound, so it costs nothing per
solve; the speed polygon gives |v| <= v_max. This linearisation is exact in the
along-track direction (the aircraft's along-track velocity during a maximum-rate turn is
exactly V cos(w t)) and relaxes only the lateral offset of the turn, which matters
little at 1-3 km. The bench (bench/bench_approach.py) reports the error of the pure
point mass, of this model and of the Dubins time against a flown reference.

Speeds are clamped into [min_speed, max_speed]: the aircraft flies at constant airspeed
and cannot be slower than its minimum speed (a reported speed below it, e.g. zero on
the ground, is treated as min_speed along the reported direction, or east without one).

Pyomo overheads
---------------
The persistent interface's `solve()` costs ~4 ms per call on top of a ~0.7 ms
warm-started LP, and it redirects the process-wide stdout/stderr file descriptors while
HiGHS runs, which would swallow other threads' log output in the onboard process. The
model is therefore translated and updated through the persistent interface
(`set_instance`, `update_variables`) and then run on the HiGHS instance that interface
owns, read back through its objective value and model status (see `_PersistentHighs`).
"""

from __future__ import annotations

import bisect
import enum
import logging
import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import pyomo.environ as pyo
from pyomo.contrib.solver.common.factory import SolverFactory

from onboard.dubins import GRAVITY

__all__ = [
    "AircraftLimits",
    "ApproachModelError",
    "ApproachTimeModel",
    "TargetSolution",
    "TargetStatus",
    "default_steps",
]

logger = logging.getLogger(__name__)

_SIDES = 16
_HALF_SIDE = math.pi / _SIDES
# The 16-gon with a vertex on the circle of radius 1 has inradius cos(pi/16); the mean of
# its radius over all directions is cos(pi/16) ln(sec + tan)(pi/16) / (pi/16).
_MEAN_RADIUS = math.cos(_HALF_SIDE) * math.log(1 / math.cos(_HALF_SIDE) + math.tan(_HALF_SIDE)) / _HALF_SIDE
SPEED_SCALE = 1.0 / _MEAN_RADIUS
ACCEL_SCALE = 1.0
_INRADIUS = math.cos(_HALF_SIDE)
# Facet normals of a 16-gon with a vertex at angle 0 (dead ahead in the heading frame).
_NORMALS = tuple(
    (math.cos((2 * i + 1) * math.pi / _SIDES), math.sin((2 * i + 1) * math.pi / _SIDES))
    for i in range(_SIDES)
)
# Distance (metres, 16-gon norm) below which the target counts as reached; HiGHS's
# primal feasibility tolerance on a km-scale model leaves residuals far below this.
_ARRIVAL_TOLERANCE_M = 1e-2


@dataclass(frozen=True)
class AircraftLimits:
    """Flight envelope used by the model, SI units."""

    min_speed: float = 15.0
    max_speed: float = 30.0
    bank_limit_deg: float = 30.0

    @property
    def max_accel(self) -> float:
        """Lateral acceleration of a coordinated turn at the bank limit, m/s^2."""
        return GRAVITY * math.tan(math.radians(self.bank_limit_deg))

    def clamp_speed(self, speed: float) -> float:
        """The airspeed the aircraft can actually be flying at."""
        return min(max(speed, self.min_speed), self.max_speed)


class TargetStatus(enum.Enum):
    """Outcome of the scan for one target."""

    SOLVED = "solved"
    UNREACHABLE = "unreachable"  # not within the horizon
    DEADLINE = "deadline"  # deadline passed or cancelled before the target was solved
    SOLVER_ERROR = "solver_error"  # HiGHS did not return an optimal LP


@dataclass(frozen=True)
class TargetSolution:
    """Approach time to one target and how it was obtained."""

    time: float | None
    status: TargetStatus
    lps: int  # LPs solved for this target


class ApproachModelError(RuntimeError):
    """The model could not be built or handed to the solver."""


def default_steps(horizon_s: float) -> tuple[float, ...]:
    """Step durations (s): 1 s for the first 20 s, then growing to 20 s steps.

    Turning happens in the first ~20 s (a 180 deg turn at 30 m/s and 30 deg bank takes
    17 s), so that part is fine-grained. Later the aircraft flies straight and the
    in-step interpolation makes long steps nearly free of error, so the steps grow
    (2 s to 40 s, 4 s to 120 s, 10 s to 300 s, then 20 s) to keep the horizon long and
    the LP small.
    """
    if horizon_s <= 0.0:
        raise ValueError(f"horizon must be positive, got {horizon_s}")
    schedule = ((20.0, 1.0), (40.0, 2.0), (120.0, 4.0), (300.0, 10.0), (math.inf, 20.0))
    steps: list[float] = []
    t = 0.0
    for until, dt in schedule:
        while t < min(until, horizon_s) - 1e-9:
            step = min(dt, horizon_s - t)
            steps.append(step)
            t += step
        if t >= horizon_s - 1e-9:
            break
    return tuple(steps)


class _PersistentHighs:
    """Pyomo's persistent HiGHS interface, run without its per-solve overhead.

    Model translation and every later bound change go through the public persistent
    API. The run itself uses the HiGHS instance the interface owns, because `solve()`
    adds ~4 ms per LP and swaps the process-wide stdout/stderr descriptors during the
    run (unsafe with other threads logging). If a future Pyomo renames that attribute,
    this falls back to the public `solve()`, slower but correct.
    """

    def __init__(self, model: pyo.ConcreteModel) -> None:
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
        self._opt = opt
        self._model = model
        self._highs: Any = getattr(opt, "_solver_model", None)
        if self._highs is not None:
            self._highs.setOptionValue("output_flag", False)
            # One thread: the machine is shared and these LPs are far too small to gain.
            self._highs.setOptionValue("threads", 1)
        else:
            logger.warning("pyomo highs interface has no _solver_model; using solve()")

    def push_bounds(self, variables: Sequence[Any]) -> None:
        """Send the current bounds of `variables` to HiGHS."""
        if variables:
            self._opt.update_variables(list(variables))

    def minimise(self) -> float | None:
        """Solve the LP; the optimal objective, or None if it is not optimal."""
        if self._highs is None:
            res = self._opt.solve(self._model)
            ok = str(res.termination_condition).endswith("convergenceCriteriaSatisfied")
            return float(res.incumbent_objective) if ok else None
        import highspy

        self._highs.run()
        if self._highs.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            return None
        return float(self._highs.getInfo().objective_function_value)


def _nearest_neighbour_order(points: Sequence[tuple[float, float]]) -> list[int]:
    """Visit order in which each point is the nearest unvisited one to the last.

    Each LP warm-starts from the previous basis; the closer the previous target, the
    fewer simplex pivots. Starts from the target nearest the aircraft. O(n^2), which is
    nothing next to one LP for the target counts of a mission.
    """
    remaining = list(range(len(points)))
    order: list[int] = []
    cx, cy = 0.0, 0.0
    while remaining:
        best = min(remaining, key=lambda i: (points[i][0] - cx) ** 2 + (points[i][1] - cy) ** 2)
        remaining.remove(best)
        order.append(best)
        cx, cy = points[best]
    return order


class ApproachTimeModel:
    """Minimum approach time from one aircraft to each target; not thread-safe.

    Build once (~0.3 s), then call `solve` as often as needed: each call costs a few
    warm-started LPs per target.
    """

    def __init__(
        self,
        limits: AircraftLimits = AircraftLimits(),
        horizon_s: float = 600.0,
        *,
        steps: Sequence[float] | None = None,
        turn_constraint: bool = True,
    ) -> None:
        """Build the model.

        `steps` overrides the time grid (default `default_steps(horizon_s)`);
        `turn_constraint=False` gives the pure point mass (kept for the bench's
        comparison).
        """
        if limits.max_speed <= 0.0 or limits.max_accel <= 0.0:
            raise ValueError(f"limits must allow motion and turns: {limits}")
        if limits.min_speed > limits.max_speed:
            raise ValueError(f"min_speed above max_speed: {limits}")
        started = time.perf_counter()
        self.limits = limits
        self.turn_constraint = turn_constraint
        self._steps = tuple(steps) if steps is not None else default_steps(horizon_s)
        if not self._steps or min(self._steps) <= 0.0:
            raise ValueError("time steps must be positive")
        times = [0.0]
        for dt in self._steps:
            times.append(times[-1] + dt)
        self._times = tuple(times)
        self._model = self._build()
        self._solver = _PersistentHighs(self._model)
        self._selected: int | None = None
        self._state: tuple[float, float] | None = None
        self.build_seconds = time.perf_counter() - started
        logger.debug(
            "approach model built: %d steps, horizon %.0f s, %.3f s",
            len(self._steps),
            self.horizon_s,
            self.build_seconds,
        )

    @property
    def horizon_s(self) -> float:
        """Length of the time grid, seconds."""
        return self._times[-1]

    @property
    def node_times(self) -> tuple[float, ...]:
        """Time of every node of the grid, seconds from now."""
        return self._times

    def _build(self) -> pyo.ConcreteModel:
        steps = self._steps
        n = len(steps)
        v_cap = self.limits.max_speed * _INRADIUS * SPEED_SCALE
        a_cap = self.limits.max_accel * _INRADIUS * ACCEL_SCALE
        m = pyo.ConcreteModel(name="approach_time")
        m.K = pyo.RangeSet(0, n)  # nodes
        m.S = pyo.RangeSet(0, n - 1)  # steps
        m.F = pyo.RangeSet(0, _SIDES - 1)  # polygon facets
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
            nx, ny = _NORMALS[f]
            return nx * b.vx[k] + ny * b.vy[k] <= v_cap

        def accel(b: Any, k: int, f: int) -> Any:
            nx, ny = _NORMALS[f]
            return nx * b.ax[k] + ny * b.ay[k] <= a_cap

        def select_x(b: Any, k: int) -> Any:
            return b.ex == b.tx - b.x[k] + b.sx[k]

        def select_y(b: Any, k: int) -> Any:
            return b.ey == b.ty - b.y[k] + b.sy[k]

        def gauge(b: Any, f: int) -> Any:
            nx, ny = _NORMALS[f]
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
        for var in (m.x[0], m.y[0], m.vy[0], m.tx, m.ty):
            var.setlb(0.0)
            var.setub(0.0)
        m.vx[0].setlb(self.limits.max_speed)
        m.vx[0].setub(self.limits.max_speed)
        return m

    def _set_state(self, speed: float) -> None:
        """Initial speed and the turn-rate bounds on the along-heading velocity."""
        if self._state == (speed, float(self.turn_constraint)):
            return
        m = self._model
        m.vx[0].setlb(speed)
        m.vx[0].setub(speed)
        changed = [m.vx[0]]
        rate = self.limits.max_accel / speed
        for k in range(1, len(self._times)):
            angle = rate * self._times[k]
            lower = speed * math.cos(angle) if self.turn_constraint and angle < math.pi else None
            m.vx[k].setlb(lower)
            changed.append(m.vx[k])
        self._solver.push_bounds(changed)
        self._state = (speed, float(self.turn_constraint))

    def _set_target(self, along: float, cross: float) -> None:
        m = self._model
        m.tx.setlb(along)
        m.tx.setub(along)
        m.ty.setlb(cross)
        m.ty.setub(cross)
        self._solver.push_bounds([m.tx, m.ty])

    def _select(self, node: int) -> None:
        m = self._model
        changed = []
        if self._selected is not None:
            for var in (m.sx[self._selected], m.sy[self._selected]):
                var.setlb(None)
                var.setub(None)
                changed.append(var)
        for var in (m.sx[node], m.sy[node]):
            var.setlb(0.0)
            var.setub(0.0)
            changed.append(var)
        self._solver.push_bounds(changed)
        self._selected = node

    def _gauge_time(self, along: float, cross: float) -> float:
        """Time to cover (along, cross) at max speed inside the speed 16-gon."""
        reach = max(nx * along + ny * cross for nx, ny in _NORMALS)
        return max(reach, 0.0) / (_INRADIUS * SPEED_SCALE * self.limits.max_speed)

    def _first_node_at_or_after(self, t: float) -> int:
        return bisect.bisect_left(self._times, t - 1e-9)

    def _gap_at(self, node: int) -> float | None:
        """Least 16-gon distance to the target at `node`; None if the LP failed."""
        self._select(node)
        return self._solver.minimise()

    def _scan(
        self,
        along: float,
        cross: float,
        deadline: float | None,
        cancel: threading.Event | None,
    ) -> TargetSolution:
        def expired() -> bool:
            if cancel is not None and cancel.is_set():
                return True
            return deadline is not None and time.monotonic() >= deadline

        speed_cap = _INRADIUS * SPEED_SCALE * self.limits.max_speed
        # Before any LP: node 0 is fixed, so its 16-gon distance is already a bound.
        bound = self._gauge_time(along, cross)
        if bound <= 0.0:
            return TargetSolution(0.0, TargetStatus.SOLVED, 0)
        self._set_target(along, cross)
        node = self._first_node_at_or_after(bound)
        last_refuted: int | None = None
        lps = 0
        while True:
            if node >= len(self._times):
                return TargetSolution(None, TargetStatus.UNREACHABLE, lps)
            if expired():
                return TargetSolution(None, TargetStatus.DEADLINE, lps)
            gap = self._gap_at(node)
            lps += 1
            if gap is None:
                logger.warning(
                    "approach LP not optimal at node %d for target (%.1f, %.1f)",
                    node,
                    along,
                    cross,
                )
                return TargetSolution(None, TargetStatus.SOLVER_ERROR, lps)
            if gap <= _ARRIVAL_TOLERANCE_M:
                break
            bound = max(bound, self._times[node] + gap / speed_cap)
            last_refuted = node
            node = max(node + 1, self._first_node_at_or_after(bound))
        # `node` is the MILP optimum. Bounds proven far from it can be loose (the
        # straight-line bound ignores the turn), so the arrival inside the last step is
        # taken from the gap at the node just before, solving it if the scan jumped it.
        if last_refuted != node - 1 and not expired():
            gap = self._gap_at(node - 1)
            lps += 1
            if gap is not None:
                bound = max(bound, self._times[node - 1] + gap / speed_cap)
        return TargetSolution(min(bound, self._times[node]), TargetStatus.SOLVED, lps)

    def solve_detailed(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        targets: Sequence[tuple[float, float]],
        deadline: float | None = None,
        cancel: threading.Event | None = None,
    ) -> list[TargetSolution]:
        """Like `solve`, with the status of every target; `cancel` acts as a deadline."""
        vx, vy = velocity
        reported = math.hypot(vx, vy)
        # Unit heading; east when the aircraft reports no velocity at all.
        hx, hy = (vx / reported, vy / reported) if reported > 1e-9 else (1.0, 0.0)
        self._set_state(self.limits.clamp_speed(reported))
        local: list[tuple[float, float]] = []
        for tx, ty in targets:
            dx = tx - position[0]
            dy = ty - position[1]
            # Heading frame: x along the velocity, y to its left. The model is symmetric
            # about the heading, so every target is mirrored to the left half-plane.
            local.append((dx * hx + dy * hy, abs(-dx * hy + dy * hx)))
        order = _nearest_neighbour_order(local)
        out: list[TargetSolution | None] = [None] * len(local)
        for i in order:
            out[i] = self._scan(local[i][0], local[i][1], deadline, cancel)
        return [sol for sol in out if sol is not None]

    def solve(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        targets: Sequence[tuple[float, float]],
        deadline: float | None = None,
    ) -> list[float | None]:
        """Minimum approach time (s) to each target.

        Positions in metres (x east, y north), velocity in m/s. None for a target
        that cannot be reached within the horizon, or whose turn came after
        `deadline` (a time.monotonic() value) had passed.
        """
        return [
            sol.time for sol in self.solve_detailed(position, velocity, targets, deadline)
        ]
