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

Targets are solved nearest first by their closed-form Dubins time (under 2 ms for 50
targets in calm air, ~25 ms in wind), so that when the budget runs out the targets left
to the fallback are the far ones, least likely to be assigned to this aircraft. (A
nearest-neighbour chain of warm starts saved no LPs and no measurable time.) Every
solution carries its Dubins time, the planner's sanity check of the model.

Wind
----
The model plans in the air mass (`onboard.planner.approach_lp`): the air velocity is the ground
velocity minus the wind; the turn bound and both 16-gons apply to it; the target drifts
through the air at minus the wind. The bound before any LP is the exact first time the
drifting 16-gon covers the target (`approach_lp.reach_time`); a refuted node's gap D
proves t' >= t_k + D / (c + gauge(wind)); the arrival inside the last step times the
gap at the ground speed of a straight leg toward the target (`fleet.geo.wind`), an
estimate as in calm air. The Dubins cap is the Dubins time in the wind. A wind faster
than `PLANNABLE_WIND_SHARE` of the airspeed is scaled down to it: nothing is flyable
against a wind as fast as the aircraft, and an estimate that large is likely wrong.

Speeds are clamped into [min_airspeed, max_airspeed] (a reported air speed of zero is
min_airspeed along the reported direction, or east without one). Times assume the
aircraft may fly at max_airspeed; if the autopilot holds a lower commanded airspeed,
build the model with that as max_airspeed.

Solvers
-------
The LP runs straight on HiGHS (`onboard.planner.approach_highs`, where the reasons are), and as
a Pyomo model for reference (`onboard.planner.approach_pyomo`); both share the LP's shape
(`onboard.planner.approach_lp`).
"""

from __future__ import annotations

import bisect
import dataclasses
import enum
import logging
import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.dubins import dubins_time_in_wind
from fleet.geo.wind import CALM_AIR, Wind, air_velocity, ground_speed_along
from onboard.planner.approach_highs import HighsLp
from onboard.planner.approach_lp import (
    SPEED_INRADIUS,
    ApproachModelError,
    BoundChange,
    LinearProgram,
    gauge,
    grid_times,
    reach_time,
)

__all__ = [
    "PLANNABLE_WIND_SHARE",
    "ApproachModelError",
    "ApproachTimeModel",
    "LpBackend",
    "TargetSolution",
    "TargetStatus",
    "along_velocity_bounds",
    "default_steps",
]

logger = logging.getLogger(__name__)

# Distance (metres, 16-gon norm) below which the target counts as reached; HiGHS's
# primal feasibility tolerance on a km-scale model leaves residuals far below this.
_ARRIVAL_TOLERANCE_M = 1e-2
_DEFAULT_LIMITS = AircraftLimits()
#: The largest wind, as a share of the airspeed, the model plans with (module docstring).
PLANNABLE_WIND_SHARE = 0.8


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
    dubins_time: float | None = None  # the closed-form Dubins time (in the wind)

    @property
    def solved(self) -> bool:
        return self.status is TargetStatus.SOLVED


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


class LpBackend(enum.Enum):
    """What runs the LP scan's linear programs."""

    HIGHS = "highs"  # `HighsLp`: the arrays straight on HiGHS (the onboard's)
    PYOMO = "pyomo"  # `onboard.planner.approach_pyomo.PyomoLp`: the Pyomo model (the reference)


def _make_lp(backend: LpBackend, limits: AircraftLimits, steps: Sequence[float]) -> LinearProgram:
    if backend is LpBackend.PYOMO:
        from onboard.planner.approach_pyomo import PyomoLp  # Pyomo: the reference only

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
        self._times = grid_times(self._steps)
        self.backend = backend
        self.lp = _make_lp(backend, limits, self._steps)
        self._selected: int | None = None
        self._speed: float | None = None
        self._wind: tuple[float, float] | None = None  # in the heading frame
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

    def _set_target(self, along: float, cross: float, wind: tuple[float, float]) -> None:
        changes: list[BoundChange] = [(("tx", 0), along, along), (("ty", 0), cross, cross)]
        if wind != self._wind:
            changes += [(("wx", 0), wind[0], wind[0]), (("wy", 0), wind[1], wind[1])]
            self._wind = wind
        self.lp.set_bounds(changes)

    def _select(self, node: int) -> None:
        changes: list[BoundChange] = []
        if self._selected is not None:
            changes += [(("sx", self._selected), None, None), (("sy", self._selected), None, None)]
        changes += [(("sx", node), 0.0, 0.0), (("sy", node), 0.0, 0.0)]
        self.lp.set_bounds(changes)
        self._selected = node

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
        wind: tuple[float, float],
        deadline: float | None,
        cancel: threading.Event | None,
    ) -> TargetSolution:
        def expired() -> bool:
            if cancel is not None and cancel.is_set():
                return True
            return deadline is not None and time.monotonic() >= deadline

        speed_cap = SPEED_INRADIUS * self.limits.max_airspeed
        # Before any LP: node 0 is fixed, so the drifting 16-gon already bounds the time.
        bound = reach_time((along, cross), wind, speed_cap)
        if bound <= 0.0:
            return TargetSolution(0.0, TargetStatus.SOLVED, 0, node=0, lp_time=0.0)
        # How fast a gap can close at most (the proof of a refuted node's bound), and
        # how fast the final straight leg closes it (its ground speed in the wind).
        closing_cap = speed_cap + gauge(wind)
        final = SPEED_INRADIUS * ground_speed_along(
            (along, cross), self.limits.max_airspeed, Wind(*wind)
        )
        self._set_target(along, cross, wind)
        node = self._first_node_at_or_after(bound)
        last_refuted: int | None = None
        last_gap = math.inf
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
            bound = max(bound, self._times[node] + gap / closing_cap)
            last_refuted, last_gap = node, gap
            node = max(node + 1, self._first_node_at_or_after(bound))
        # `node` is the MILP optimum. Bounds proven far from it can be loose (the
        # straight-line bound ignores the turn), so the arrival inside the last step is
        # taken from the gap at the node just before, solving it if the scan jumped it.
        gap = last_gap if last_refuted == node - 1 else None
        if gap is None and not expired():
            gap = self._gap_at(node - 1)
            lps += 1
        if gap is not None:
            bound = max(bound, self._times[node - 1] + gap / final)
        arrival = min(bound, self._times[node])
        return TargetSolution(arrival, TargetStatus.SOLVED, lps, node, arrival)

    def solve_detailed(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        targets: Sequence[tuple[float, float]],
        deadline: float | None = None,
        cancel: threading.Event | None = None,
        wind: Wind = CALM_AIR,
    ) -> list[TargetSolution]:
        """Like `solve`, with the status of every target; `cancel` acts as a deadline."""
        values = (*position, *velocity, *wind, *(c for target in targets for c in target))
        if not all(math.isfinite(v) for v in values):
            raise ValueError("position, velocity, wind and targets must be finite")
        # The aircraft's velocity through the air: what it turns and holds its speed in.
        vx, vy = air_velocity(velocity, wind)
        reported = math.hypot(vx, vy)
        # Unit heading; east when the aircraft reports no velocity at all.
        hx, hy = (vx / reported, vy / reported) if reported > 1e-9 else (1.0, 0.0)
        speed = self.limits.clamp_airspeed(reported)
        radius = self.limits.turn_radius(speed)
        wind = wind.at_most(PLANNABLE_WIND_SHARE * speed)
        wind_along = wind.east * hx + wind.north * hy
        wind_cross = -wind.east * hy + wind.north * hx
        self._set_state(speed)
        local: list[tuple[float, float, tuple[float, float]]] = []
        for tx, ty in targets:
            dx = tx - position[0]
            dy = ty - position[1]
            # Heading frame: x along the air velocity, y to its left. The model is
            # symmetric about the heading, so every target is mirrored to the left
            # half-plane, and the wind with it.
            cross = -dx * hy + dy * hx
            side = 1.0 if cross >= 0.0 else -1.0
            local.append((dx * hx + dy * hy, abs(cross), (wind_along, side * wind_cross)))
        dubins = [
            dubins_time_in_wind((0.0, 0.0), (speed, 0.0), (along, cross), radius, Wind(*drift))
            for along, cross, drift in local
        ]
        out: list[TargetSolution | None] = [None] * len(local)
        for i in sorted(range(len(local)), key=dubins.__getitem__):
            along, cross, drift = local[i]
            sol = dataclasses.replace(
                self._scan(along, cross, drift, deadline, cancel), dubins_time=dubins[i]
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
        wind: Wind = CALM_AIR,
    ) -> list[float | None]:
        """Minimum approach time (s) to each target.

        Positions in metres (x east, y north), velocity over the ground and `wind` (the
        air mass's velocity) in m/s. None for a target
        that cannot be reached within the horizon, or whose turn came after
        `deadline` (a time.monotonic() value) had passed.
        """
        solutions = self.solve_detailed(position, velocity, targets, deadline, wind=wind)
        return [sol.time for sol in solutions]
