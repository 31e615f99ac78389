"""Background approach-time planning: the thesis's RunMILP / IsMILPRunning / GetElapsedTime.

The thesis's MILPHandler ran CPLEX in a pthread so that the serial loop kept talking to
the autopilot while the optimisation ran; the loop polled IsMILPRunning() on every
iteration and read the result when it turned false. `PlannerWorker` keeps that contract
for the approach-time model:

=====================  ======================================================
thesis                 here
=====================  ======================================================
``RunMILP()``          ``run(request) -> bool`` (False if a run is under way)
``IsMILPRunning()``    ``is_running()``
``GetElapsedTime()``   ``elapsed()`` (float seconds, not whole ``time_t``)
global output vars     ``result()`` (a `PlanResult`, handed out once)
=====================  ======================================================

None of these calls blocks on the solver. `run()` while a run is under way supersedes
it: the running solve stops at its next LP, its answer is dropped (it would be another
mission's approach times), and the new request runs next.

The model is built in the worker thread, so the constructor does not block either:
right after construction (~0.1 s), or, with `build_at_start=False`, when
`prepare(cruise_speed)` first names the speed the aircraft holds (the onboard process
calls it on the first GPS telemetry), so the first mission does not rebuild it. HiGHS
is loaded there, in the worker thread, not when this module is: an onboard process
comes up and joins the fleet without it. The model is the LP straight on HiGHS
(`onboard.planner.approach_highs.HighsLp`): neither Pyomo nor numpy is ever loaded in an
onboard process.

Every run ends with a time for every target. The model stops starting LPs once the
request's budget has elapsed; targets it did not reach get the analytic Dubins time
in the request's wind (`fleet.geo.dubins.dubins_time_in_wind`), as do targets beyond
the model's horizon, and `PlanResult.fallback` says which. An exception inside the
model is logged and turned into a result with the Dubins time for every target and
the exception in `error`; the model is then rebuilt before the next run, because a
failure half-way through a bound update could leave the solver and the model's
bookkeeping out of step.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.dubins import dubins_time_in_wind
from fleet.geo.visibility import Route
from fleet.geo.wind import CALM_AIR, Wind, air_velocity, airspeed
from onboard.native_thread import name_native_thread
from onboard.planner.route_plan import route_targets

if TYPE_CHECKING:
    from onboard.planner.approach_model import ApproachTimeModel, TargetSolution

__all__ = ["PlanRequest", "PlanResult", "PlannerWorker", "fallback_time"]

logger = logging.getLogger(__name__)

_JOIN_TIMEOUT_S = 5.0
_DEFAULT_LIMITS = AircraftLimits()
#: How much faster than the Dubins time at the same speed (in the same wind) a model
#: answer may honestly be, beyond `SANITY_MIN_TURN_RADII` turn radii: the turn
#: relaxation's worst case (4 %) plus the speed 16-gon's (1.3 %), measured in
#: docs/benchmarks.md. Faster is a defect.
MODEL_STATED_ERROR = 0.055
#: Inside this many turn radii the relaxation is knowingly optimistic: no sanity check.
SANITY_MIN_TURN_RADII = 3.0
#: A cruise speed this close to the model's top speed reuses the model.
CRUISE_SPEED_TOLERANCE = 0.5
#: The largest wind, as a share of the airspeed, planned with: the model's own
#: (`onboard.planner.approach_model.PLANNABLE_WIND_SHARE`; a test checks they agree).
PLANNABLE_WIND_SHARE = 0.8


@dataclass(frozen=True)
class PlanRequest:
    """One planning job: the aircraft's state and the targets, in local metres."""

    position: tuple[float, float]
    velocity: tuple[float, float]
    targets: tuple[tuple[float, float], ...]
    budget_s: float
    #: The speed the aircraft holds, m/s: the module never changes airspeed, so the
    #: model's top speed is this one. None: the limits' `max_airspeed`.
    cruise_speed: float | None = None
    #: No-fly zones (rings in the same local metres) every route keeps out of
    #: (onboard.planner.route_plan); none: every time is the approach model's to the target.
    zones: tuple[tuple[tuple[float, float], ...], ...] = ()
    #: The wind to plan in (the air mass's velocity, m/s); `velocity` is over the ground.
    wind: Wind = CALM_AIR

    def __post_init__(self) -> None:
        # A list passed by the caller becomes a tuple, so the request stays immutable.
        object.__setattr__(self, "position", (float(self.position[0]), float(self.position[1])))
        object.__setattr__(self, "velocity", (float(self.velocity[0]), float(self.velocity[1])))
        object.__setattr__(self, "targets", tuple((float(x), float(y)) for x, y in self.targets))
        object.__setattr__(self, "wind", Wind(float(self.wind[0]), float(self.wind[1])))
        values = [*self.position, *self.velocity, *self.wind]
        values += [c for t in self.targets for c in t]
        if not all(math.isfinite(v) for v in values):
            raise ValueError("position, velocity, wind and targets must be finite")
        if not self.budget_s >= 0.0:
            raise ValueError(f"budget must be >= 0 s, got {self.budget_s}")


@dataclass(frozen=True)
class PlanResult:
    """Approach time (s) to every target of `request`, in the request's order."""

    request: PlanRequest
    times: tuple[float, ...]
    fallback: tuple[bool, ...]  # True where times[i] is the Dubins time, not the model's
    solve_seconds: float  # from run() to the result, build included if it happened then
    #: CPU time of the worker thread for this result: what the solve cost, however long
    #: it waited for a core on a busy machine.
    cpu_seconds: float = 0.0
    error: str | None = None  # the exception that made every target fall back
    lps: int = 0  # LPs solved for this result
    defects: int = 0  # model answers faster than the Dubins time allows (logged)
    #: With zones, each target's route (None: no route reaches it, and its time is inf).
    routes: tuple[Route | None, ...] = ()

    @property
    def model_times(self) -> int:
        return self.fallback.count(False)

    @property
    def fallback_times(self) -> int:
        return self.fallback.count(True)


def fallback_time(
    limits: AircraftLimits,
    position: tuple[float, float],
    velocity: tuple[float, float],
    target: tuple[float, float],
    wind: Wind = CALM_AIR,
) -> float:
    """Dubins time to `target` at the current airspeed in `wind`, clamped to the flight
    envelope.

    `velocity` is over the ground; the air velocity is it minus the wind. An air speed
    outside [min_airspeed, max_airspeed] (zero on the ground) is clamped like the model
    does, and so is the wind (`PLANNABLE_WIND_SHARE` of the speed); with no velocity at
    all the heading is taken as east.
    """
    air = air_velocity(velocity, wind)
    reported = math.hypot(*air)
    speed = limits.clamp_airspeed(reported)
    if reported > 1e-9:
        flown = (air[0] * speed / reported, air[1] * speed / reported)
    else:
        flown = (speed, 0.0)
    radius = limits.turn_radius(speed)
    # The model's own share (onboard.planner.approach_model.PLANNABLE_WIND_SHARE), not imported:
    # that module loads HiGHS.
    planned = wind.at_most(PLANNABLE_WIND_SHARE * speed)
    return dubins_time_in_wind(position, flown, target, radius, planned)


def _default_model(limits: AircraftLimits, horizon_s: float) -> ApproachTimeModel:
    from onboard.planner.approach_model import ApproachTimeModel  # HiGHS: here only

    return ApproachTimeModel(limits, horizon_s)


class PlannerWorker:
    """Runs an `ApproachTimeModel` in a background thread; poll it from the link loop."""

    def __init__(
        self,
        limits: AircraftLimits = _DEFAULT_LIMITS,
        horizon_s: float = 600.0,
        *,
        model_factory: Callable[[], ApproachTimeModel] | None = None,
        notify: Callable[[], None] | None = None,
        build_at_start: bool = True,
    ) -> None:
        """Start the worker thread, which builds the model at once.

        `model_factory` replaces the default `ApproachTimeModel(limits, horizon_s)`
        (tests use it to inject failures); `limits` also drive the Dubins fallback.
        `notify` is called from the worker thread when a result is ready, so a caller
        that sleeps until something happens can wake up and take it.
        """
        self._limits = limits
        #: The airframe's limits, whatever the cruise speed: routes around no-fly zones are
        #: inflated on them, as the route flown is (onboard.route_flight).
        self._airframe = limits
        self._notify = notify
        self._custom_factory = model_factory is not None
        self._factory: Callable[[], ApproachTimeModel] = model_factory or (
            lambda: _default_model(self._limits, horizon_s)
        )
        self._prepare: float | None = None  # a cruise speed to build the model at
        self._build_at_start = build_at_start
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._cancel = threading.Event()  #: closing: stop every run
        #: Stops the current run: set by a newer request, and by closing.
        self._supersede = threading.Event()
        self._pending: PlanRequest | None = None
        self._running = False
        self._closed = False
        self._started: float | None = None
        self._finished: float | None = None
        self._result: PlanResult | None = None
        self._model: ApproachTimeModel | None = None
        self._build_error: str | None = None
        self._thread = threading.Thread(target=self._loop, name="planner", daemon=True)
        self._thread.start()

    # -- the thesis's interface -------------------------------------------------------

    def run(self, request: PlanRequest) -> bool:
        """Start planning `request` (True); a run under way is superseded by it.

        A result not yet taken with `result()` is discarded.
        """
        with self._lock:
            if self._closed:
                raise RuntimeError("planner worker is closed")
            if self._running:
                self._supersede.set()
            self._running = True
            self._started = time.monotonic()
            self._finished = None
            self._result = None
            self._pending = request
            self._wake.notify()
        return True

    def prepare(self, cruise_speed: float) -> None:
        """Build the model now, at `cruise_speed`, if it is not built yet (no-op after)."""
        with self._lock:
            if self._model is None and self._prepare is None and math.isfinite(cruise_speed):
                self._prepare = cruise_speed
                self._wake.notify()

    def model_speed(self) -> float | None:
        """The top speed (m/s) of the model built, None while none is built."""
        with self._lock:
            return None if self._model is None else self._limits.max_airspeed

    def is_running(self) -> bool:
        """True from `run()` until the result is ready."""
        with self._lock:
            return self._running

    def elapsed(self) -> float:
        """Seconds since the current run started (its duration once done; 0 before any)."""
        with self._lock:
            if self._started is None:
                return 0.0
            end = self._finished if self._finished is not None else time.monotonic()
            return end - self._started

    def result(self) -> PlanResult | None:
        """The finished run's result, once; None while running or if already taken."""
        with self._lock:
            result, self._result = self._result, None
            return result

    def close(self) -> None:
        """Stop the thread, abandoning any run at its next LP. Idempotent."""
        with self._lock:
            self._closed = True
            self._cancel.set()
            self._supersede.set()
            self._wake.notify()
        if threading.current_thread() is not self._thread:
            self._thread.join(_JOIN_TIMEOUT_S)
            if self._thread.is_alive():
                logger.warning("planner worker did not stop within %.1f s", _JOIN_TIMEOUT_S)

    def __enter__(self) -> PlannerWorker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the worker thread ------------------------------------------------------------

    def _loop(self) -> None:
        name_native_thread()
        if self._build_at_start:
            self._ensure_model()
        while True:
            with self._lock:
                while self._pending is None and self._prepare is None and not self._closed:
                    self._wake.wait()
                if self._closed:
                    self._running = False
                    return
                request, self._pending = self._pending, None
                prepare, self._prepare = self._prepare, None
                if request is None:
                    if prepare is not None and self._model is None:
                        self._adopt_cruise_speed(prepare)
                        self._ensure_model()
                    continue
                started = self._started if self._started is not None else time.monotonic()
                if not self._closed:
                    self._supersede.clear()
            result = self._plan(request, started)
            with self._lock:
                if self._pending is not None:
                    continue  # superseded while it ran: the newer request runs next
                self._result = result
                self._finished = time.monotonic()
                self._running = False
            if self._notify is not None:
                self._notify()

    def _ensure_model(self) -> ApproachTimeModel | None:
        """Build the model if there is none; a failure is logged and retried next run."""
        if self._model is None and not self._cancel.is_set():
            try:
                self._model = self._factory()
                self._build_error = None
            except Exception as exc:
                logger.exception("building the approach model failed")
                self._build_error = f"{type(exc).__name__}: {exc}"
        return self._model

    def _adopt_cruise_speed(self, cruise_speed: float | None) -> None:
        """Rebuild the model (about 50 ms) when the aircraft's speed has moved on."""
        if cruise_speed is None or self._custom_factory:
            return
        speed = self._airframe.clamp_airspeed(cruise_speed)
        if abs(speed - self._limits.max_airspeed) > CRUISE_SPEED_TOLERANCE:
            logger.info("approach model rebuilt for a cruise speed of %.1f m/s", speed)
            self._limits = replace(self._limits, max_airspeed=speed)
            self._model = None

    def _plan(self, request: PlanRequest, started: float) -> PlanResult:
        """The approach times of `request`; with zones, of the routes around them."""
        if not request.zones:
            return self._plan_aims(request, started)
        routed = route_targets(
            request.position,
            request.velocity,
            request.targets,
            request.zones,
            self._airframe,
            request.wind,
            request.cruise_speed,
        )
        result = self._plan_aims(replace(request, targets=routed.aims), started)
        times = tuple(routed.time(i, t) for i, t in enumerate(result.times))
        return replace(result, request=request, times=times, routes=routed.routes)

    def _plan_aims(self, request: PlanRequest, started: float) -> PlanResult:
        cpu_started = time.thread_time()
        self._adopt_cruise_speed(request.cruise_speed)
        deadline = started + request.budget_s
        solutions: Sequence[TargetSolution] = ()
        error: str | None = None
        model = self._ensure_model()
        if model is None:
            error = f"approach model unavailable: {self._build_error or 'closing'}"
        try:
            if model is not None:
                solutions = model.solve_detailed(
                    request.position,
                    request.velocity,
                    request.targets,
                    deadline=deadline,
                    cancel=self._supersede,
                    wind=request.wind,
                )
        except Exception as exc:
            logger.exception("approach model failed; Dubins fallback for every target")
            error = f"{type(exc).__name__}: {exc}"
            solutions = ()
            self._model = None  # rebuilt before the next run
        times: list[float] = []
        fallback: list[bool] = []
        lps = 0
        for i, target in enumerate(request.targets):
            sol = solutions[i] if i < len(solutions) else None
            if sol is not None:
                lps += sol.lps
            if sol is not None and sol.solved and sol.time is not None:
                times.append(sol.time)
                fallback.append(False)
            else:
                times.append(
                    fallback_time(
                        self._limits, request.position, request.velocity, target, request.wind
                    )
                )
                fallback.append(True)
        stopped = self._cancel.is_set() or self._supersede.is_set()
        if any(fallback) and error is None and not stopped:
            logger.info(
                "planner: %d of %d targets used the Dubins fallback",
                sum(fallback),
                len(fallback),
            )
        return PlanResult(
            request=request,
            times=tuple(times),
            fallback=tuple(fallback),
            solve_seconds=time.monotonic() - started,
            cpu_seconds=time.thread_time() - cpu_started,
            error=error,
            lps=lps,
            defects=self._sanity_check(request, solutions),
        )

    def _sanity_check(self, request: PlanRequest, solutions: Sequence[TargetSolution]) -> int:
        """Count (and log) model answers faster than the Dubins time by more than the
        model's stated error, where the check holds (beyond a few turn radii)."""
        speed = self._limits.clamp_airspeed(airspeed(request.velocity, request.wind))
        near = SANITY_MIN_TURN_RADII * self._limits.turn_radius(speed)
        defects = []
        for i, (sol, target) in enumerate(zip(solutions, request.targets, strict=False)):
            if not sol.solved or sol.lp_time is None or sol.dubins_time is None:
                continue
            far = math.dist(target, request.position) > near
            if far and sol.lp_time < sol.dubins_time * (1.0 - MODEL_STATED_ERROR):
                defects.append(
                    f"target {i}: model {sol.lp_time:.1f} s < Dubins {sol.dubins_time:.1f} s"
                )
        if defects:
            logger.warning(
                "approach model defect: %d answer(s) faster than the Dubins time by more "
                "than %.1f %%: %s",
                len(defects),
                100 * MODEL_STATED_ERROR,
                "; ".join(defects),
            )
        return len(defects)
