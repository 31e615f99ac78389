"""Minimum approach time from one UAV to each of a set of targets (Richards-How model).

One linear program per UAV is built once, handed to HiGHS once, and re-solved as the
aircraft's state and the targets change by updating variable bounds only: no constraint
or coefficient changes after construction (see "Solvers" below for Pyomo's part).

Model
-----
A point mass, double integrator in x/y metres with piecewise-constant acceleration, on
a variable time grid (`default_steps`: 2 s steps for the first 20 s, where turning
happens, then 5, 10, 20 and 30 s steps, so a 600 s horizon takes 43 steps). Speed at
every node and acceleration in every step stay inside 16-gons with a vertex dead ahead:
max airspeed, and a_max = g tan(bank_limit), the lateral acceleration of a coordinated
turn at the bank limit. The acceleration 16-gon is inscribed in its circle. The speed
16-gon is scaled to the circle's mean radius (x1.013): a 16-gon is 1.3 % slower than
the circle on average, which, inscribed, showed up as a +1.3 % bias on every approach
time; scaled, the bias is zero and the error is +/-1.3 % depending on the direction of
the final leg (straight ahead it is 1.3 % fast).

Everything is posed in the aircraft's heading frame (origin at the aircraft, x along its
velocity, y to its left), so the state enters as bounds on node 0 and the turn
constraint below as bounds on vx. The model is symmetric about the heading, so targets
on the right are mirrored to the left.

Turn-rate linearisation (why the model is not a pure point mass)
---------------------------------------------------------------
A free point mass brakes and reverses in a few seconds; the aircraft flies at constant
airspeed V and turns at rate w = a_max / V. Against a flown bank-limited reference the
pure point mass is up to 16 % optimistic for targets behind the aircraft at 1-3 km.
The aircraft's heading after t seconds differs from its initial heading by at most
theta(t) = w t, so its velocity lies on an arc of half-angle theta(t), whose convex hull
is the circular segment {|v| <= V, v . h0 >= V cos theta}. The model therefore bounds
the along-heading velocity from below: vx_k >= V cos(w t_k) while w t_k < pi. This is
exact along track (the along-track velocity in a maximum-rate turn is exactly
V cos(w t)) and relaxes only the lateral offset of the turn, which matters little
beyond a few turn radii. Measured (docs/benchmarks.md, approach-time model, 30 m/s, 1-3 km, all
bearings): worst error 16 % -> 4 %, median 0.5 %. A further bound tried, lateral
offset >= r (1 - vx/V) (valid for a constant-speed aircraft turning toward the target),
made arrival exactly at a node infeasible without weaving, up to 25 % pessimistic, and
was dropped. Inside ~3 turn
radii the relaxation stays optimistic (a point inside the turn circle needs a loop the
point mass does not fly); see the benchmark figures.

"LP scan" instead of arrival binaries
-------------------------------------
Richards and How minimise the arrival step with one binary per step. Here the same
model has no binaries: for a candidate node k one LP minimises D, the 16-gon distance
from the node-k position to the target. D = 0 (to 1 cm) means "can be on the target
at node k"; the first such k is exactly the MILP optimum (the bench checks this against
a MILP with arrival binaries). D > 0 also proves a lower bound: velocity stays inside
the speed 16-gon, of inradius c, so a trajectory on the target at t' was within
c (t' - t_k) of it (16-gon norm) at t_k, hence t' >= t_k + D / c. The scan starts at
the straight-line bound and jumps to the first node past each proven bound instead of
trying every node, so a target costs about 2 LPs. The node is selected through the bounds
of one slack pair per node (fixed at 0 on the tested node, free elsewhere).

Arrival time inside the last step: the best of those lower bounds, capped at t_k,
always including t_{k-1} + D_{k-1} / c (the LP at k-1 is solved if the scan jumped over
it). That bound is the exact continuous arrival when the final leg is straight at full
speed, which is how the aircraft ends every approach, and it removes the rounding up
to the grid (up to a whole 10-30 s step). Bounds proven further back are loose (the
straight-line bound ignores the turn): used alone they were up to 7 % optimistic.

Dubins cap
----------
The LP places the arrival on a grid node, so it cannot see the aircraft pass through a
target between nodes: a target a few metres dead ahead would need the point mass to be
there at t = 2 s, i.e. to turn round (~17 s instead of 0.1 s). The Dubins path at the
current speed is flyable, so the true minimum time cannot exceed it: the reported time
is min(LP, Dubins) (`TargetSolution.lp_time` keeps the LP's own). Beyond a few turn
radii the cap binds only where the 16-gon makes the LP up to 1.3 % slow (about half the
bearings); it never binds where the LP is below the Dubins time (the turn relaxation,
or an aircraft that can speed up to max_airspeed). The bench's flown reference is a Dubins
path by construction, so its "LP alone" rows are the figures that judge the model.

Targets are solved nearest first by their closed-form Dubins time (0.1-0.2 ms for 50
targets), so that when the budget runs out the targets left to the fallback are the
far ones, least likely to be assigned to this aircraft. (A nearest-neighbour chain warm-
starts each LP from a similar basis; on the benchmark's 50 ring targets it saved no LPs
and no measurable time against this order.) Every solution carries its Dubins time, the
planner's sanity check of the model (onboard.planner_worker).

Speeds are clamped into [min_airspeed, max_airspeed]: a reported speed below the minimum
(e.g. zero on the ground) is treated as min_airspeed along the reported direction, or east
without one; one above the maximum (a ground speed with tailwind) as max_airspeed. Wind is
not modelled. Times assume the aircraft may fly at max_airspeed; if the autopilot holds a
lower commanded airspeed, build the model with that as max_airspeed.

Solvers: the onboard's LP straight on HiGHS, the Pyomo model as the reference
---------------------------------------------------------------------------
The model was written in Pyomo (`onboard.approach_pyomo.build_point_mass`) and handed to
HiGHS through Pyomo's persistent interface. Pyomo and numpy, which highspy's Python
layer imports, hold ~37 MB resident in every onboard process (issue 14: fifty onboards
on one box) and nothing of them is used after the model is translated: the LP scan only
changes variable bounds and runs HiGHS. So `point_mass_lp` states the same LP as arrays,
row for row, column for column, in the order Pyomo's translation gives them, and `HighsLp`
passes it to HiGHS's compiled core (`load_highs_core`: without highspy's numpy layer) and
changes its bounds in place. The LP HiGHS receives is then identical to Pyomo's (a test
compares both), so HiGHS solves the same problems from the same bases: the times are
equal (the tests and `bench/bench_approach.py` compare them). `LpBackend.PYOMO` runs the
scan on the Pyomo model, for the tests, the bench and its MILP reference.

HiGHS runs with one thread and no output. Pyomo's public persistent `solve()` added
~2-4 ms per LP and redirected the process-wide stdout/stderr descriptors while HiGHS ran;
neither path uses it (see `onboard.approach_pyomo`).
"""

from __future__ import annotations

import bisect
import dataclasses
import enum
import importlib.machinery
import importlib.util
import logging
import math
import os
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any, Protocol

from fleet.errors import FleetError
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.dubins import dubins_path_length

__all__ = [
    "ApproachModelError",
    "ApproachTimeModel",
    "BoundChange",
    "Column",
    "HighsLp",
    "LinearProgram",
    "LpBackend",
    "PointMassLp",
    "TargetSolution",
    "TargetStatus",
    "along_velocity_bounds",
    "default_steps",
    "load_highs_core",
    "point_mass_lp",
]

logger = logging.getLogger(__name__)

SIDES = 16
_HALF_SIDE = math.pi / SIDES
#: Inradius of the acceleration 16-gon, inscribed in the unit circle.
ACCEL_INRADIUS = math.cos(_HALF_SIDE)
#: Inradius of the speed 16-gon scaled to a mean radius of 1: the inscribed 16-gon's mean
#: radius is cos(h) ln(sec h + tan h) / h with h = pi/16, so this is h / ln(sec h + tan h).
SPEED_INRADIUS = _HALF_SIDE / math.log(1.0 / math.cos(_HALF_SIDE) + math.tan(_HALF_SIDE))
#: Facet normals of a 16-gon with a vertex at angle 0 (dead ahead in the heading frame).
NORMALS = tuple(
    (math.cos((2 * i + 1) * math.pi / SIDES), math.sin((2 * i + 1) * math.pi / SIDES))
    for i in range(SIDES)
)
# Distance (metres, 16-gon norm) below which the target counts as reached; HiGHS's
# primal feasibility tolerance on a km-scale model leaves residuals far below this.
_ARRIVAL_TOLERANCE_M = 1e-2
_DEFAULT_LIMITS = AircraftLimits()


class TargetStatus(enum.Enum):
    """Outcome of the scan for one target."""

    SOLVED = "solved"
    UNREACHABLE = "unreachable"  # not within the horizon
    DEADLINE = "deadline"  # deadline passed or cancelled before the target was solved
    SOLVER_ERROR = "solver_error"  # HiGHS did not return an optimal LP


@dataclass(frozen=True)
class TargetSolution:
    """Approach time to one target and how it was obtained."""

    time: float | None  # min(lp_time, Dubins time) when solved
    status: TargetStatus
    lps: int  # LPs solved for this target
    node: int | None = None  # first node on the target: the arrival-step MILP's optimum
    lp_time: float | None = None  # the LP scan's own estimate, before the Dubins cap
    dubins_time: float | None = None  # the closed-form Dubins time at the current speed

    @property
    def solved(self) -> bool:
        return self.status is TargetStatus.SOLVED


class ApproachModelError(FleetError, RuntimeError):
    """The model could not be built or handed to the solver."""


def default_steps(horizon_s: float) -> tuple[float, ...]:
    """Step durations (s): 2 s for the first 20 s, then 5, 10, 20 and 30 s steps.

    Turning happens in the first ~20 s (a 180 deg turn at 30 m/s and 30 deg bank takes
    17 s), so that part is fine-grained; later the aircraft flies straight and the
    in-step interpolation makes long steps nearly free of error. A 600 s horizon takes
    43 steps. Measured against a flown reference (bench/bench_approach.py), 1 s steps in
    the first 20 s and 2-4 s steps to 120 s (83 steps) were no more accurate, and the
    simplex pivots per LP grow with the number of nodes before the arrival, so this
    grid is ~2.5x faster.
    """
    if horizon_s <= 0.0:
        raise ValueError(f"horizon must be positive, got {horizon_s}")
    schedule = ((20.0, 2.0), (60.0, 5.0), (120.0, 10.0), (300.0, 20.0), (math.inf, 30.0))
    steps: list[float] = []
    t = 0.0
    for until, dt in schedule:
        while t < min(until, horizon_s) - 1e-9:
            step = min(dt, until - t, horizon_s - t)
            steps.append(step)
            t += step
    return tuple(steps)


#: A variable of the LP: its name in the Pyomo model and its index (0 for a scalar).
Column = tuple[str, int]
#: New lower and upper bounds of a variable; None is unbounded.
BoundChange = tuple[Column, float | None, float | None]


class LpBackend(enum.Enum):
    """What runs the LP scan's linear programs."""

    HIGHS = "highs"  # `HighsLp`: the arrays straight on HiGHS (the onboard's)
    PYOMO = "pyomo"  # `onboard.approach_pyomo.PyomoLp`: the Pyomo model (the reference)


class LinearProgram(Protocol):
    """The point-mass LP, changed through variable bounds only."""

    def set_bounds(self, changes: Sequence[BoundChange]) -> None: ...

    def minimise(self) -> float | None:
        """The optimal objective, or None if HiGHS found no optimum."""
        ...


@dataclass
class PointMassLp:
    """`build_point_mass`'s LP as arrays, in HiGHS's row-wise form.

    Columns are numbered in order of first appearance in the rows, and rows come in the
    Pyomo model's constraint order, with its coefficients: the order Pyomo's HiGHS
    translation produces, so that HiGHS receives an identical LP.
    """

    columns: dict[Column, int] = field(default_factory=dict)
    col_lower: list[float] = field(default_factory=list)
    col_upper: list[float] = field(default_factory=list)
    row_lower: list[float] = field(default_factory=list)
    row_upper: list[float] = field(default_factory=list)
    starts: list[int] = field(default_factory=list)  # first entry of each row
    index: list[int] = field(default_factory=list)
    value: list[float] = field(default_factory=list)

    def add_row(self, terms: Sequence[tuple[Column, float]], lower: float, upper: float) -> None:
        self.starts.append(len(self.index))
        for column, coefficient in terms:
            number = self.columns.get(column)
            if number is None:
                number = self.columns[column] = len(self.columns)
                self.col_lower.append(-math.inf)
                self.col_upper.append(math.inf)
            self.index.append(number)
            self.value.append(coefficient)
        self.row_lower.append(lower)
        self.row_upper.append(upper)

    def bound(self, column: Column, lower: float, upper: float) -> None:
        number = self.columns[column]
        self.col_lower[number] = lower
        self.col_upper[number] = upper

    def to_mps(self) -> str:
        """The LP in free-format MPS, minimising the last column (`gap`); rows, columns
        and every number (`repr`, which reads back exactly) in this LP's order."""
        rows = len(self.row_lower)
        kinds = []
        rhs = []
        for r, (lower, upper) in enumerate(zip(self.row_lower, self.row_upper, strict=True)):
            if lower == upper:
                kinds.append(f" E r{r}")
                value = lower
            elif lower == -math.inf and upper < math.inf:
                kinds.append(f" L r{r}")
                value = upper
            elif upper == math.inf and lower > -math.inf:
                kinds.append(f" G r{r}")
                value = lower
            else:
                raise ValueError(f"row {r}: bounds [{lower}, {upper}] are not one-sided")
            if value != 0.0:
                rhs.append(f" rhs r{r} {value!r}")
        by_column: list[list[tuple[int, float]]] = [[] for _ in self.columns]
        for r in range(rows):
            end = self.starts[r + 1] if r + 1 < rows else len(self.index)
            for j in range(self.starts[r], end):
                by_column[self.index[j]].append((r, self.value[j]))
        last = len(by_column) - 1
        entries = []
        for c, column in enumerate(by_column):
            entries += [f" c{c} r{r} {value!r}" for r, value in column]
            if c == last:
                entries.append(f" c{c} obj 1.0")
        bounds = []
        for c, (lower, upper) in enumerate(zip(self.col_lower, self.col_upper, strict=True)):
            if lower == upper:
                bounds.append(f" FX bnd c{c} {lower!r}")
            elif lower == -math.inf and upper == math.inf:
                bounds.append(f" FR bnd c{c}")
            else:
                if lower == -math.inf:
                    bounds.append(f" MI bnd c{c}")
                elif lower != 0.0:
                    bounds.append(f" LO bnd c{c} {lower!r}")
                if upper != math.inf:
                    bounds.append(f" UP bnd c{c} {upper!r}")
        lines = ["NAME approach_time", "ROWS", " N obj", *kinds, "COLUMNS", *entries]
        lines += ["RHS", *rhs, "BOUNDS", *bounds, "ENDATA", ""]
        return "\n".join(lines)


def point_mass_lp(limits: AircraftLimits, steps: Sequence[float]) -> PointMassLp:
    """The point-mass LP on the time grid `steps`, in the heading frame.

    Variables x, y, vx, vy on nodes 0..n, ax, ay on steps 0..n-1, the slack pair sx, sy
    per node (fixed to 0 on the node being tested, free elsewhere), the gap vector ex,
    ey (target minus the tested node's position), the target tx, ty (fixed through its
    bounds) and the objective `gap` >= 0, the 16-gon norm of (ex, ey). Node 0 is at the
    origin flying along +x at max speed. `onboard.approach_pyomo.build_point_mass` is
    the same model in Pyomo; a coefficient written as Pyomo computes it (0.5 * dt * dt).
    """
    n = len(steps)
    v_cap = limits.max_airspeed * SPEED_INRADIUS
    a_cap = limits.max_accel * ACCEL_INRADIUS
    lp = PointMassLp()
    for pos, vel, acc in (("x", "vx", "ax"), ("y", "vy", "ay")):
        for k, dt in enumerate(steps):  # pos[k+1] = pos[k] + dt vel[k] + dt^2/2 acc[k]
            terms = [((pos, k + 1), 1.0), ((pos, k), -1.0), ((vel, k), -dt)]
            lp.add_row([*terms, ((acc, k), -(0.5 * dt * dt))], 0.0, 0.0)
    for vel, acc in (("vx", "ax"), ("vy", "ay")):
        for k, dt in enumerate(steps):  # vel[k+1] = vel[k] + dt acc[k]
            lp.add_row([((vel, k + 1), 1.0), ((vel, k), -1.0), ((acc, k), -dt)], 0.0, 0.0)
    # Node 0 is fixed by bounds, so its speed needs no polygon.
    for k in range(1, n + 1):
        for nx, ny in NORMALS:
            lp.add_row([(("vx", k), nx), (("vy", k), ny)], -math.inf, v_cap)
    for k in range(n):
        for nx, ny in NORMALS:
            lp.add_row([(("ax", k), nx), (("ay", k), ny)], -math.inf, a_cap)
    for pos, gap, target, slack in (("x", "ex", "tx", "sx"), ("y", "ey", "ty", "sy")):
        for k in range(n + 1):  # gap = target - pos[k] + slack[k]
            terms = [((gap, 0), 1.0), ((target, 0), -1.0), ((pos, k), 1.0), ((slack, k), -1.0)]
            lp.add_row(terms, 0.0, 0.0)
    for nx, ny in NORMALS:  # gap >= the 16-gon's facet distance
        lp.add_row([(("ex", 0), nx), (("ey", 0), ny), (("gap", 0), -1.0)], -math.inf, 0.0)
    # The heading frame puts the aircraft at the origin flying along +x.
    for column in (("x", 0), ("y", 0), ("vy", 0), ("tx", 0), ("ty", 0)):
        lp.bound(column, 0.0, 0.0)
    lp.bound(("vx", 0), limits.max_airspeed, limits.max_airspeed)
    lp.bound(("gap", 0), 0.0, math.inf)
    return lp


def load_highs_core() -> ModuleType:
    """HiGHS's compiled core (`highspy._core`), without highspy's Python layer.

    `import highspy` also imports numpy (~12 MB resident per process) for array helpers
    this LP does not need: the core takes Python lists and scalars. So the extension is
    loaded on its own and registered under its own name, so that a later `import highspy`
    (Pyomo's, in the tests) reuses the same module instead of loading it twice. If
    highspy's layout ever changes, the whole package is imported instead.
    """
    name = "highspy._core"
    loaded = sys.modules.get(name)
    if loaded is not None:
        return loaded
    package = importlib.util.find_spec("highspy")
    if package is None:
        raise ApproachModelError("HiGHS (highspy) is not installed")
    locations = list(package.submodule_search_locations or ())
    spec = importlib.machinery.PathFinder.find_spec(name, locations)
    if spec is None or spec.loader is None:
        logger.info("highspy has no %s of its own: importing the whole package", name)
        return importlib.import_module(name)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _read_mps(highs: Any, mps: str) -> Any:
    """Hand `mps` to HiGHS through a private file, removed at once; HiGHS's status.

    The file is created exclusively (`O_EXCL`, mode 0600) under a name that holds the
    process ID, so no other process can hand HiGHS its own LP: `tempfile` would do the
    same but loads `random`, `shutil`, `bz2` and `lzma` into every onboard (~0.3 MB).
    """
    directory = os.environ.get("TMPDIR") or "/tmp"
    for attempt in range(100):
        path = os.path.join(directory, f"approach-lp-{os.getpid()}-{attempt}.mps")
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:  # a leftover of a killed process with a reused PID
            continue
        try:
            with os.fdopen(fd, "w", encoding="ascii") as file:
                file.write(mps)
            return highs.readModel(path)
        finally:
            os.unlink(path)
    raise ApproachModelError(f"no free file name for the approach-time LP in {directory}")


class HighsLp:
    """`point_mass_lp` on one HiGHS instance, changed through column bounds only.

    The LP reaches HiGHS as a free-format MPS file (written to a private file and
    read back at once): every array-taking call of highspy's core converts through numpy,
    which this avoids importing; the file's numbers are written exactly (`repr`).
    """

    def __init__(self, limits: AircraftLimits, steps: Sequence[float]) -> None:
        core: Any = load_highs_core()
        lp = point_mass_lp(limits, steps)
        highs = core._Highs()
        highs.setOptionValue("output_flag", False)
        # One thread: the machine is shared and these LPs are far too small to gain.
        highs.setOptionValue("threads", 1)
        status = _read_mps(highs, lp.to_mps())
        if status != core.HighsStatus.kOk or highs.getNumCol() != len(lp.columns):
            raise ApproachModelError(f"HiGHS refused the approach-time LP: {status}")
        self.columns = lp.columns
        self.highs: Any = highs
        self._optimal = core.HighsModelStatus.kOptimal

    def set_bounds(self, changes: Sequence[BoundChange]) -> None:
        for column, lower, upper in changes:
            self.highs.changeColBounds(
                self.columns[column],
                -math.inf if lower is None else lower,
                math.inf if upper is None else upper,
            )

    def minimise(self) -> float | None:
        self.highs.run()
        if self.highs.getModelStatus() != self._optimal:
            # Drop the basis, so that the next LP does not warm-start from a failed one.
            self.highs.clearSolver()
            return None
        return float(self.highs.getInfo().objective_function_value)


def _make_lp(backend: LpBackend, limits: AircraftLimits, steps: Sequence[float]) -> LinearProgram:
    if backend is LpBackend.PYOMO:
        from onboard.approach_pyomo import PyomoLp  # Pyomo: the reference only

        return PyomoLp(limits, steps)
    return HighsLp(limits, steps)


def along_velocity_bounds(
    limits: AircraftLimits, node_times: Sequence[float], speed: float
) -> list[float | None]:
    """Lower bound on the along-heading velocity at every node (None: unbounded).

    V cos(w t) while w t < pi, with w = a_max / V the turn rate at the bank limit: the
    convex hull of the velocities reachable by turning at most w t (module docstring).
    Node 0 is the current velocity itself.
    """
    rate = limits.max_accel / speed
    bounds: list[float | None] = [speed]
    for t in node_times[1:]:
        angle = rate * t
        bounds.append(speed * math.cos(angle) if angle < math.pi else None)
    return bounds


class ApproachTimeModel:
    """Minimum approach time from one aircraft to each target; not thread-safe.

    Build once (~0.1 s), then call `solve` as often as needed: each call costs about
    two warm-started LPs per target.
    """

    def __init__(
        self,
        limits: AircraftLimits = _DEFAULT_LIMITS,
        horizon_s: float = 600.0,
        *,
        steps: Sequence[float] | None = None,
        turn_constraint: bool = True,
        backend: LpBackend = LpBackend.HIGHS,
    ) -> None:
        """Build the model.

        `steps` overrides the time grid (default `default_steps(horizon_s)`);
        `turn_constraint=False` gives the pure point mass (kept for the bench's
        comparison); `backend=LpBackend.PYOMO` runs the scan on the Pyomo model (the
        reference; the same LP, the same times).
        """
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
        self.backend = backend
        self.lp = _make_lp(backend, limits, self._steps)
        self._selected: int | None = None
        self._speed: float | None = None
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
    def steps(self) -> tuple[float, ...]:
        """Duration of every step of the grid, seconds."""
        return self._steps

    @property
    def node_times(self) -> tuple[float, ...]:
        """Time of every node of the grid, seconds from now."""
        return self._times

    def _set_state(self, speed: float) -> None:
        """Initial speed and the turn-rate bounds on the along-heading velocity."""
        if self._speed == speed:
            return
        changes: list[BoundChange] = [(("vx", 0), speed, speed)]
        lowers = along_velocity_bounds(self.limits, self._times, speed)
        for k in range(1, len(self._times)):
            changes.append((("vx", k), lowers[k] if self.turn_constraint else None, None))
        self.lp.set_bounds(changes)
        self._speed = speed

    def _set_target(self, along: float, cross: float) -> None:
        self.lp.set_bounds([(("tx", 0), along, along), (("ty", 0), cross, cross)])

    def _select(self, node: int) -> None:
        changes: list[BoundChange] = []
        if self._selected is not None:
            changes += [(("sx", self._selected), None, None), (("sy", self._selected), None, None)]
        changes += [(("sx", node), 0.0, 0.0), (("sy", node), 0.0, 0.0)]
        self.lp.set_bounds(changes)
        self._selected = node

    def _gauge_time(self, along: float, cross: float) -> float:
        """Time to cover (along, cross) at max speed inside the speed 16-gon."""
        reach = max(nx * along + ny * cross for nx, ny in NORMALS)
        return max(reach, 0.0) / (SPEED_INRADIUS * self.limits.max_airspeed)

    def _first_node_at_or_after(self, t: float) -> int:
        return bisect.bisect_left(self._times, t - 1e-9)

    def _gap_at(self, node: int) -> float | None:
        """Least 16-gon distance to the target at `node`; None if the LP failed."""
        self._select(node)
        return self.lp.minimise()

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

        speed_cap = SPEED_INRADIUS * self.limits.max_airspeed
        # Before any LP: node 0 is fixed, so its 16-gon distance is already a bound.
        bound = self._gauge_time(along, cross)
        if bound <= 0.0:
            return TargetSolution(0.0, TargetStatus.SOLVED, 0, node=0, lp_time=0.0)
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
        arrival = min(bound, self._times[node])
        return TargetSolution(arrival, TargetStatus.SOLVED, lps, node, arrival)

    def solve_detailed(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        targets: Sequence[tuple[float, float]],
        deadline: float | None = None,
        cancel: threading.Event | None = None,
    ) -> list[TargetSolution]:
        """Like `solve`, with the status of every target; `cancel` acts as a deadline."""
        values = (*position, *velocity, *(c for target in targets for c in target))
        if not all(math.isfinite(v) for v in values):
            raise ValueError("position, velocity and targets must be finite")
        vx, vy = velocity
        reported = math.hypot(vx, vy)
        # Unit heading; east when the aircraft reports no velocity at all.
        hx, hy = (vx / reported, vy / reported) if reported > 1e-9 else (1.0, 0.0)
        speed = self.limits.clamp_airspeed(reported)
        radius = self.limits.turn_radius(speed)
        self._set_state(speed)
        local: list[tuple[float, float]] = []
        for tx, ty in targets:
            dx = tx - position[0]
            dy = ty - position[1]
            # Heading frame: x along the velocity, y to its left. The model is symmetric
            # about the heading, so every target is mirrored to the left half-plane.
            local.append((dx * hx + dy * hy, abs(-dx * hy + dy * hx)))
        dubins = [
            dubins_path_length((0.0, 0.0), 0.0, (along, cross), radius) / speed
            for along, cross in local
        ]
        out: list[TargetSolution | None] = [None] * len(local)
        for i in sorted(range(len(local)), key=dubins.__getitem__):
            along, cross = local[i]
            sol = dataclasses.replace(
                self._scan(along, cross, deadline, cancel), dubins_time=dubins[i]
            )
            # The Dubins path is flyable at the current speed, so the minimum time
            # cannot exceed it (see "Dubins cap" in the module docstring).
            if sol.time is not None and dubins[i] < sol.time:
                sol = dataclasses.replace(sol, time=dubins[i])
            out[i] = sol
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
        return [sol.time for sol in self.solve_detailed(position, velocity, targets, deadline)]
