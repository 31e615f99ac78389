"""The approach-time LP straight on HiGHS: what the onboard process runs.

Why not through Pyomo
---------------------
The model was written in Pyomo (`onboard.planner.approach_pyomo.build_point_mass`) and handed to
HiGHS through Pyomo's persistent interface. Pyomo and numpy, which highspy's Python
layer imports, hold ~37 MB resident in every onboard process (fifty onboards
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
neither path uses it (see `onboard.planner.approach_pyomo`).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import logging
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from fleet.geo.aircraft import AircraftLimits
from onboard.planner.approach_lp import (
    ACCEL_INRADIUS,
    NORMALS,
    SPEED_INRADIUS,
    ApproachModelError,
    BoundChange,
    Column,
    grid_times,
)

__all__ = ["HighsLp", "PointMassLp", "load_highs_core", "point_mass_lp"]

logger = logging.getLogger(__name__)


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
    ey (the target, drifted by the wind to node k's time, minus the tested node's
    position), the target tx, ty and the wind wx, wy (fixed through their bounds, calm
    here) and the objective `gap` >= 0, the 16-gon norm of (ex, ey). Node 0 is at the
    origin flying along +x at max speed. `onboard.planner.approach_pyomo.build_point_mass` is
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
    times = grid_times(steps)
    selection = (("x", "ex", "tx", "sx", "wx"), ("y", "ey", "ty", "sy", "wy"))
    for pos, gap, target, slack, wind in selection:
        for k in range(n + 1):  # gap = target - wind t_k - pos[k] + slack[k]
            terms = [((gap, 0), 1.0), ((target, 0), -1.0), ((pos, k), 1.0), ((slack, k), -1.0)]
            if k:  # node 0: no drift yet
                terms.append(((wind, 0), times[k]))
            lp.add_row(terms, 0.0, 0.0)
    for nx, ny in NORMALS:  # gap >= the 16-gon's facet distance
        lp.add_row([(("ex", 0), nx), (("ey", 0), ny), (("gap", 0), -1.0)], -math.inf, 0.0)
    # The heading frame puts the aircraft at the origin flying along +x.
    for column in (("x", 0), ("y", 0), ("vy", 0), ("tx", 0), ("ty", 0), ("wx", 0), ("wy", 0)):
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
