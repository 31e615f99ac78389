"""Benchmark of the onboard approach-time model: solve times and prediction error.

Run: ``.venv/bin/python -m bench.bench_approach`` (about 10 s on 2 shared cores).
Prints markdown tables:

1. Model build time, then solve time for 1, 4, 10 and 50 targets (one UAV, the model
   already built, a new aircraft state every repetition), with two references measured
   in the same run on the 4-target case: a fresh Pyomo MILP per target (arrival
   binaries, Richards-How; also checks that the LP scan finds the same arrival step) and
   the same LP scan through the persistent interface's public `solve()`.
2. The onboard's LP straight on HiGHS against the same LP scan on the Pyomo model (the
   reference): build time, solve time and whether every time is identical.
3. Relative error of the predicted approach time against a flown arrival time, over
   24 bearings (0-345 deg) at 1, 2 and 3 km, for the pure point mass, the model as
   shipped (point mass + turn-rate bound) and the analytic Dubins fallback.

The flown reference (`fly_pure_pursuit`) is a small deterministic fixed-wing kinematic
model, not the project's simulator: constant airspeed, heading turned at the bank-limit
rate toward the target until it points at it, then straight, 20 ms steps.
"""

from __future__ import annotations

import logging
import math
import random
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import pyomo.environ as pyo
from pyomo.contrib.solver.common.factory import SolverFactory

from fleet.geo.aircraft import AircraftLimits, turn_radius
from fleet.geo.dubins import dubins_time_to_point
from onboard.planner.approach_model import ApproachTimeModel, LpBackend, along_velocity_bounds
from onboard.planner.approach_pyomo import PyomoLp, build_point_mass
from tests.support.pure_pursuit import fly_pure_pursuit

logger = logging.getLogger(__name__)

Point = tuple[float, float]

_SEED = 20240601
_REPEATS = 5
_TARGET_COUNTS = (1, 4, 10, 50)
_RING_BEARINGS_DEG = tuple(range(0, 360, 15))
_RING_RANGES_M = (1000.0, 2000.0, 3000.0)
_NEAR_RANGES_M = (300.0, 600.0)


def milp_arrival_node(
    limits: AircraftLimits, steps: Sequence[float], speed: float, target: Point
) -> int | None:
    """Arrival step of a fresh Richards-How MILP (one binary per node) for one target.

    `target` is in the heading frame (x along the velocity). The dynamics, polygons and
    turn bound are the shipped model's (`build_point_mass`), so the optimum must equal
    the LP scan's arrival node.
    """
    m = build_point_mass(limits, steps)
    times = [0.0]
    for dt in steps:
        times.append(times[-1] + dt)
    m.vx[0].setlb(speed)
    m.vx[0].setub(speed)
    for k, lower in enumerate(along_velocity_bounds(limits, times, speed)):
        if k > 0:
            m.vx[k].setlb(lower)
    for component in (m.objective, m.select_x, m.select_y, m.gauge):
        component.deactivate()
    n = len(steps)
    m.N = pyo.RangeSet(1, n)
    m.arrive = pyo.Var(m.N, domain=pyo.Binary)
    # Big-M per node: no position can be further from the target than this.
    reach = [
        1.05 * limits.max_airspeed * t + max(abs(target[0]), abs(target[1])) + 1.0 for t in times
    ]

    def x_hi(b: Any, k: int) -> Any:
        return b.x[k] - target[0] <= reach[k] * (1 - b.arrive[k])

    def x_lo(b: Any, k: int) -> Any:
        return target[0] - b.x[k] <= reach[k] * (1 - b.arrive[k])

    def y_hi(b: Any, k: int) -> Any:
        return b.y[k] - target[1] <= reach[k] * (1 - b.arrive[k])

    def y_lo(b: Any, k: int) -> Any:
        return target[1] - b.y[k] <= reach[k] * (1 - b.arrive[k])

    m.x_hi = pyo.Constraint(m.N, rule=x_hi)
    m.x_lo = pyo.Constraint(m.N, rule=x_lo)
    m.y_hi = pyo.Constraint(m.N, rule=y_hi)
    m.y_lo = pyo.Constraint(m.N, rule=y_lo)
    m.once = pyo.Constraint(expr=sum(m.arrive[k] for k in m.N) == 1)
    m.arrival = pyo.Objective(expr=sum(times[k] * m.arrive[k] for k in m.N))
    opt: Any = SolverFactory("highs")
    opt.config.raise_exception_on_nonoptimal_result = False
    opt.config.load_solutions = False
    res = opt.solve(m)
    if res.incumbent_objective is None:
        return None
    res.solution_loader.load_vars()
    return int(max(m.N, key=lambda k: pyo.value(m.arrive[k])))


def _random_targets(rng: random.Random, count: int) -> list[Point]:
    out = []
    for _ in range(count):
        bearing = rng.uniform(0.0, math.tau)
        dist = rng.uniform(500.0, 5000.0)
        out.append((dist * math.cos(bearing), dist * math.sin(bearing)))
    return out


def _random_state(rng: random.Random, speed: float) -> tuple[Point, Point]:
    heading = rng.uniform(0.0, math.tau)
    position = (rng.uniform(-200.0, 200.0), rng.uniform(-200.0, 200.0))
    return position, (speed * math.cos(heading), speed * math.sin(heading))


def _to_heading_frame(position: Point, velocity: Point, target: Point) -> Point:
    speed = math.hypot(velocity[0], velocity[1])
    hx, hy = velocity[0] / speed, velocity[1] / speed
    dx, dy = target[0] - position[0], target[1] - position[1]
    return dx * hx + dy * hy, -dx * hy + dy * hx


@dataclass(frozen=True)
class _Timing:
    median_s: float
    worst_s: float
    lps_per_target: float


def _time_solves(model: ApproachTimeModel, count: int, rng: random.Random) -> _Timing:
    samples = []
    lps = 0
    speed = model.limits.max_airspeed
    for _ in range(_REPEATS):
        targets = _random_targets(rng, count)
        position, velocity = _random_state(rng, speed)
        started = time.perf_counter()
        sols = model.solve_detailed(position, velocity, targets)
        samples.append(time.perf_counter() - started)
        lps += sum(s.lps for s in sols)
    return _Timing(statistics.median(samples), max(samples), lps / (_REPEATS * count))


def _timing_table(limits: AircraftLimits) -> list[str]:
    rng = random.Random(_SEED)
    started = time.perf_counter()
    model = ApproachTimeModel(limits)
    build = time.perf_counter() - started
    # One throw-away solve: the first LP starts without a basis.
    model.solve((0.0, 0.0), (limits.max_airspeed, 0.0), [(1000.0, 0.0)])
    lines = [
        f"Model build (the LP straight on HiGHS, as onboard): {build:.3f} s, "
        f"{len(model.steps)} steps, horizon {model.horizon_s:.0f} s.",
        "",
        "| targets | median s | worst s | LPs per target |",
        "|---:|---:|---:|---:|",
    ]
    four: _Timing | None = None
    for count in _TARGET_COUNTS:
        timing = _time_solves(model, count, rng)
        if count == 4:
            four = timing
        lines.append(
            f"| {count} | {timing.median_s:.3f} | {timing.worst_s:.3f} | "
            f"{timing.lps_per_target:.1f} |"
        )
    assert four is not None
    return lines + _reference_lines(model, limits, rng)


def _reference_lines(
    model: ApproachTimeModel, limits: AircraftLimits, rng: random.Random
) -> list[str]:
    """The shipped LP scan against the public persistent `solve()` and a fresh MILP, on
    one 4-target case."""
    targets = _random_targets(rng, 4)
    position, velocity = _random_state(rng, limits.max_airspeed)
    started = time.perf_counter()
    sols = model.solve_detailed(position, velocity, targets)
    scan_s = time.perf_counter() - started
    started = time.perf_counter()
    milp_nodes = [
        milp_arrival_node(
            limits,
            model.steps,
            limits.max_airspeed,
            _to_heading_frame(position, velocity, t),
        )
        for t in targets
    ]
    milp_s = time.perf_counter() - started
    agree = sum(1 for s, n in zip(sols, milp_nodes, strict=True) if s.node == n)

    public = ApproachTimeModel(limits, backend=LpBackend.PYOMO)
    assert isinstance(public.lp, PyomoLp)
    public.lp.highs = None  # force the public persistent solve() path
    public.solve((0.0, 0.0), (limits.max_airspeed, 0.0), [(1000.0, 0.0)])
    started = time.perf_counter()
    public.solve(position, velocity, targets)
    public_s = time.perf_counter() - started

    return [
        "",
        "| 4 targets, same case | seconds | ratio to LP scan |",
        "|---|---:|---:|",
        f"| LP scan, the LP on HiGHS (shipped) | {scan_s:.3f} | 1.0 |",
        f"| same LP scan on the Pyomo model via the public `solve()` | {public_s:.3f} "
        f"| {public_s / scan_s:.1f} |",
        f"| fresh Pyomo MILP per target (arrival binaries) | {milp_s:.3f} "
        f"| {milp_s / scan_s:.1f} |",
        "",
        f"Arrival step, LP scan vs MILP optimum: {agree}/{len(targets)} identical "
        f"(LP scan nodes {[s.node for s in sols]}, MILP nodes {milp_nodes}).",
    ]


@dataclass(frozen=True)
class _ErrorStats:
    median: float
    worst: float
    bias: float
    cases: int


def _errors(predicted: Sequence[float | None], flown: Sequence[float | None]) -> _ErrorStats:
    rel = [
        (p - f) / f
        for p, f in zip(predicted, flown, strict=True)
        if p is not None and f is not None and f > 0.0
    ]
    mags = [abs(e) for e in rel]
    return _ErrorStats(
        statistics.median(mags), max(mags, default=math.nan), statistics.mean(rel), len(rel)
    )


def _ring(ranges: Sequence[float]) -> list[Point]:
    return [
        (r * math.cos(math.radians(b)), r * math.sin(math.radians(b)))
        for r in ranges
        for b in _RING_BEARINGS_DEG
    ]


def _error_row(
    label: str,
    predict: Callable[[Sequence[Point]], Sequence[float | None]],
    limits: AircraftLimits,
    ranges: Sequence[float],
) -> str:
    speed = limits.max_airspeed
    cases = _ring(ranges)
    flown = [fly_pure_pursuit((0.0, 0.0), (speed, 0.0), c, limits) for c in cases]
    stats = _errors(predict(cases), flown)
    rng_text = ", ".join(f"{r / 1000:g}" for r in ranges)
    return (
        f"| {label} | {speed:g} | {rng_text} | {stats.cases} | {100 * stats.median:.1f} % "
        f"| {100 * stats.worst:.1f} % | {100 * stats.bias:+.1f} % |"
    )


def _error_table() -> list[str]:
    lines = [
        "| predictor | speed m/s | ranges km | cases | median abs error | worst abs error "
        "| mean signed error |",
        "|---|---:|---|---:|---:|---:|---:|",
    ]
    for speed in (30.0, 20.0):
        limits = AircraftLimits(max_airspeed=speed)
        velocity = (speed, 0.0)
        pure = ApproachTimeModel(limits, turn_constraint=False)
        shipped = ApproachTimeModel(limits)
        radius = turn_radius(speed, limits.bank_limit_deg)

        def lp_alone(
            cases: Sequence[Point], m: ApproachTimeModel, v: Point = velocity
        ) -> list[float | None]:
            return [s.lp_time for s in m.solve_detailed((0.0, 0.0), v, cases)]

        def by_pure(cases: Sequence[Point], m: ApproachTimeModel = pure) -> list[float | None]:
            return lp_alone(cases, m)

        def by_lp(cases: Sequence[Point], m: ApproachTimeModel = shipped) -> list[float | None]:
            return lp_alone(cases, m)

        def by_model(
            cases: Sequence[Point], m: ApproachTimeModel = shipped, v: Point = velocity
        ) -> list[float | None]:
            return m.solve((0.0, 0.0), v, cases)

        def by_dubins(
            cases: Sequence[Point], r: float = radius, v: Point = velocity
        ) -> list[float | None]:
            return [dubins_time_to_point((0.0, 0.0), v, c, r) for c in cases]

        rows = (
            ("pure point mass (LP alone)", by_pure, _RING_RANGES_M),
            ("point mass + turn bound (LP alone)", by_lp, _RING_RANGES_M),
            ("**shipped: + turn bound, Dubins cap**", by_model, _RING_RANGES_M),
            ("Dubins time (the fallback)", by_dubins, _RING_RANGES_M),
            ("near field: + turn bound (LP alone)", by_lp, _NEAR_RANGES_M),
            ("near field: shipped", by_model, _NEAR_RANGES_M),
        )
        for label, predict, ranges in rows:
            lines.append(_error_row(label, predict, limits, ranges))
    return lines


def _backend_table(limits: AircraftLimits) -> list[str]:
    """The onboard's LP on HiGHS against the Pyomo reference: same cases, same times?"""
    rng = random.Random(_SEED + 1)
    models = {}
    builds = {}
    for backend in LpBackend:
        started = time.perf_counter()
        models[backend] = ApproachTimeModel(limits, backend=backend)
        builds[backend] = time.perf_counter() - started
        models[backend].solve((0.0, 0.0), (limits.max_airspeed, 0.0), [(1000.0, 0.0)])
    lines = [
        f"Build: LP on HiGHS {builds[LpBackend.HIGHS]:.3f} s, Pyomo model + persistent "
        f"interface {builds[LpBackend.PYOMO]:.3f} s (Pyomo already imported).",
        "",
        "| targets | cases | HiGHS median s | Pyomo median s | identical solutions |",
        "|---:|---:|---:|---:|---:|",
    ]
    for count in _TARGET_COUNTS:
        seconds: dict[LpBackend, list[float]] = {backend: [] for backend in LpBackend}
        same = total = 0
        for _ in range(2 * _REPEATS):
            targets = _random_targets(rng, count)
            position, velocity = _random_state(rng, limits.max_airspeed)
            answers = {}
            for backend, model in models.items():
                started = time.perf_counter()
                answers[backend] = model.solve_detailed(position, velocity, targets)
                seconds[backend].append(time.perf_counter() - started)
            pairs = zip(answers[LpBackend.HIGHS], answers[LpBackend.PYOMO], strict=True)
            same += sum(1 for a, b in pairs if a == b)
            total += count
        lines.append(
            f"| {count} | {2 * _REPEATS} | {statistics.median(seconds[LpBackend.HIGHS]):.3f} "
            f"| {statistics.median(seconds[LpBackend.PYOMO]):.3f} | {same}/{total} |"
        )
    return lines


def main() -> None:
    """Run both benchmarks and print their tables."""
    logging.basicConfig(level=logging.WARNING)
    started = time.perf_counter()
    limits = AircraftLimits()
    print("## Approach-time model: solve time (one UAV)\n")
    print("\n".join(_timing_table(limits)))
    print("\n## The onboard's LP on HiGHS against the Pyomo model (reference)\n")
    print("\n".join(_backend_table(limits)))
    print("\n## Approach-time model: prediction error against a flown arrival\n")
    print("\n".join(_error_table()))
    print(f"\n(bench wall time {time.perf_counter() - started:.1f} s)")


if __name__ == "__main__":
    main()
