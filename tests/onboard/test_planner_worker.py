"""Tests of the background planner (onboard.planner.planner_worker): the RunMILP contract."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence

import pytest

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.wind import CALM_AIR, Wind
from onboard.planner.approach_model import (
    ApproachTimeModel,
    TargetSolution,
    TargetStatus,
)
from onboard.planner.planner_worker import (
    PLANNABLE_WIND_SHARE,
    PlannerWorker,
    PlanRequest,
    PlanResult,
    fallback_time,
)

LIMITS = AircraftLimits()
V = LIMITS.max_airspeed
TARGETS = ((1500.0, 0.0), (-1000.0, 800.0), (0.0, -2500.0))
WAIT_S = 30.0  # generous: a timeout here means a hang, not a slow machine


def request(
    budget_s: float = 10.0, targets: Sequence[tuple[float, float]] = TARGETS
) -> PlanRequest:
    return PlanRequest(
        position=(0.0, 0.0), velocity=(V, 0.0), targets=tuple(targets), budget_s=budget_s
    )


def wait_for_clock_past(instant: float) -> None:
    """Return once the monotonic clock reads later than `instant` (an observable tick)."""
    while time.monotonic() <= instant:
        time.sleep(0.001)


def wait_result(worker: PlannerWorker) -> PlanResult:
    give_up = time.monotonic() + WAIT_S
    while worker.is_running():
        assert time.monotonic() < give_up, "planner never finished"
        time.sleep(0.005)
    result = worker.result()
    assert result is not None
    return result


class StandInModel(ApproachTimeModel):
    """A stand-in model (no Pyomo): a subclass says in `answer` what every solve returns."""

    def __init__(self) -> None:  # no super(): nothing to build
        pass

    def solve_detailed(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        targets: Sequence[tuple[float, float]],
        deadline: float | None = None,
        cancel: threading.Event | None = None,
        wind: Wind = CALM_AIR,
    ) -> list[TargetSolution]:
        return self.answer(targets, cancel)

    def answer(
        self, targets: Sequence[tuple[float, float]], cancel: threading.Event | None
    ) -> list[TargetSolution]:
        raise NotImplementedError


class GatedModel(StandInModel):
    """Waits for `gate`, then answers 10 s per target."""

    def __init__(self, gate: threading.Event) -> None:  # no super(): nothing to build
        self.gate = gate

    def answer(
        self, targets: Sequence[tuple[float, float]], cancel: threading.Event | None
    ) -> list[TargetSolution]:
        while not self.gate.wait(0.01):
            if cancel is not None and cancel.is_set():
                return [TargetSolution(None, TargetStatus.DEADLINE, 0) for _ in targets]
        return [TargetSolution(10.0, TargetStatus.SOLVED, 1) for _ in targets]


class FailingModel(StandInModel):
    """Its solve raises."""

    def answer(
        self, targets: Sequence[tuple[float, float]], cancel: threading.Event | None
    ) -> list[TargetSolution]:
        raise RuntimeError("solver exploded")


@pytest.fixture
def make_worker() -> Iterator[Callable[..., PlannerWorker]]:
    workers: list[PlannerWorker] = []

    def make(factory: Callable[[], ApproachTimeModel] | None = None) -> PlannerWorker:
        worker = PlannerWorker(LIMITS, model_factory=factory)
        workers.append(worker)
        return worker

    yield make
    for worker in workers:
        worker.close()


def test_run_does_not_block_and_reports_progress(
    make_worker: Callable[..., PlannerWorker],
) -> None:
    gate = threading.Event()
    worker = make_worker(lambda: GatedModel(gate))
    assert worker.elapsed() == 0.0
    assert worker.run(request())  # returns while the model is held at the gate
    assert worker.is_running()
    assert worker.result() is None
    first = worker.elapsed()
    assert first > 0.0
    wait_for_clock_past(time.monotonic())
    assert worker.elapsed() > first  # counting while it runs
    gate.set()
    result = wait_result(worker)
    assert result.times == (10.0, 10.0, 10.0)
    assert result.fallback == (False, False, False)
    assert result.error is None
    assert result.request.targets == TARGETS
    assert worker.result() is None  # handed out once
    done = worker.elapsed()
    wait_for_clock_past(time.monotonic())
    assert worker.elapsed() == done  # frozen once finished, though the clock moved on
    assert worker.run(request())  # free again
    wait_result(worker)


def test_a_newer_request_supersedes_the_run_under_way(
    make_worker: Callable[..., PlannerWorker],
) -> None:
    gate = threading.Event()
    worker = make_worker(lambda: GatedModel(gate))
    old = request()
    assert worker.run(old)  # held at the gate until cancelled
    newer = PlanRequest((0.0, 0.0), (V, 0.0), TARGETS[:2], budget_s=10.0)
    assert worker.run(newer)  # the old run stops at once; its answer is dropped
    gate.set()
    result = wait_result(worker)
    assert result.request is newer and result.times == (10.0, 10.0)
    assert worker.result() is None  # only the newer request's answer is handed out


def test_real_model_matches_direct_solve(make_worker: Callable[..., PlannerWorker]) -> None:
    worker = make_worker()
    assert worker.run(request(budget_s=30.0))
    result = wait_result(worker)
    direct = ApproachTimeModel(LIMITS).solve((0.0, 0.0), (V, 0.0), TARGETS)
    assert result.fallback == (False, False, False)
    assert result.times == pytest.approx(direct, rel=1e-6)
    assert result.solve_seconds > 0.0 and result.lps >= len(TARGETS)


def test_tiny_budget_falls_back_to_dubins_and_says_so(
    make_worker: Callable[..., PlannerWorker],
) -> None:
    worker = make_worker()
    assert worker.run(request(budget_s=0.0))
    result = wait_result(worker)
    assert result.fallback == (True, True, True)
    assert result.error is None
    for target, t in zip(TARGETS, result.times, strict=True):
        assert t == pytest.approx(fallback_time(LIMITS, (0.0, 0.0), (V, 0.0), target))
    assert result.times[0] == pytest.approx(1500.0 / V)


def test_beyond_horizon_gets_dubins_time(make_worker: Callable[..., PlannerWorker]) -> None:
    worker = make_worker()
    far = (30_000.0, 0.0)  # 1000 s at 30 m/s: past the 600 s horizon
    assert worker.run(request(targets=[(1500.0, 0.0), far]))
    result = wait_result(worker)
    assert result.fallback == (False, True)
    assert result.times[1] == pytest.approx(1000.0)


def test_solver_exception_is_survived(make_worker: Callable[..., PlannerWorker]) -> None:
    builds: list[int] = []
    gate = threading.Event()
    gate.set()

    def factory() -> ApproachTimeModel:
        builds.append(1)
        return FailingModel() if len(builds) == 1 else GatedModel(gate)

    worker = make_worker(factory)
    assert worker.run(request())
    result = wait_result(worker)
    assert result.error is not None and "solver exploded" in result.error
    assert result.fallback == (True, True, True)
    assert all(math.isfinite(t) for t in result.times)
    # The thread is alive and rebuilt its model: the next run is answered by the model.
    assert worker.run(request())
    again = wait_result(worker)
    assert again.error is None and again.fallback == (False, False, False)
    assert len(builds) == 2


def test_model_build_failure_is_survived(make_worker: Callable[..., PlannerWorker]) -> None:
    def factory() -> ApproachTimeModel:
        raise OSError("no solver here")

    worker = make_worker(factory)
    assert worker.run(request())
    result = wait_result(worker)
    assert result.error is not None and "no solver here" in result.error
    assert result.fallback == (True, True, True)


def test_close_abandons_a_run_and_is_idempotent(
    make_worker: Callable[..., PlannerWorker],
) -> None:
    gate = threading.Event()  # never opened: only close() can end the run
    worker = make_worker(lambda: GatedModel(gate))
    assert worker.run(request())
    worker.close()
    worker.close()
    assert not worker.is_running()
    with pytest.raises(RuntimeError, match="closed"):
        worker.run(request())


def test_request_validation() -> None:
    with pytest.raises(ValueError, match="budget must be >= 0"):
        request(budget_s=-1.0)
    with pytest.raises(ValueError, match="must be finite"):
        request(targets=[(math.nan, 0.0)])
    listed = PlanRequest(position=(0, 0), velocity=(V, 0), targets=[(1, 2)], budget_s=1)  # type: ignore[arg-type]
    assert listed.targets == ((1.0, 2.0),)


def test_fallback_time_clamps_speed() -> None:
    # Stationary: min speed, heading east.
    t = fallback_time(LIMITS, (0.0, 0.0), (0.0, 0.0), (1500.0, 0.0))
    assert t == pytest.approx(1500.0 / LIMITS.min_airspeed)
    # Faster than max airspeed (tailwind): max speed.
    t = fallback_time(LIMITS, (0.0, 0.0), (0.0, 45.0), (0.0, 3000.0))
    assert t == pytest.approx(3000.0 / V)


def test_cruise_speed_rebuilds_the_model_for_the_speed_flown() -> None:
    ahead = ((2200.0, 0.0),)
    with PlannerWorker() as worker:
        times: dict[float, list[float]] = {}
        for speed in (22.0, 28.0, 22.0):
            request = PlanRequest((0.0, 0.0), (speed, 0.0), ahead, 30.0, cruise_speed=speed)
            assert worker.run(request)
            deadline = time.monotonic() + 30.0
            while (result := worker.result()) is None and time.monotonic() < deadline:
                time.sleep(0.01)
            assert result is not None and not any(result.fallback)
            times.setdefault(speed, []).append(result.times[0])
    # 2.2 km straight ahead: ~100 s at 22 m/s, ~79 s at 28 m/s, the same again at 22.
    assert times[22.0][0] == pytest.approx(100.0, rel=0.03)
    assert times[28.0][0] == pytest.approx(2200.0 / 28.0, rel=0.03)
    assert times[22.0][1] == pytest.approx(times[22.0][0])


def test_prepare_builds_the_model_at_cruise_speed_before_the_first_run(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with PlannerWorker(build_at_start=False) as worker:
        assert worker.model_speed() is None  # nothing built before the speed is known
        worker.prepare(22.0)
        give_up = time.monotonic() + WAIT_S
        while worker.model_speed() is None:
            assert time.monotonic() < give_up, "model never built"
            time.sleep(0.01)
        assert worker.model_speed() == 22.0
        worker.prepare(28.0)  # built already: the next run adopts a new speed, not this
        caplog.set_level("INFO", logger="onboard.planner.planner_worker")
        run = PlanRequest((0.0, 0.0), (22.0, 0.0), ((2200.0, 0.0),), 30.0, cruise_speed=22.0)
        assert worker.run(run)
        result = wait_result(worker)
    assert not any(result.fallback)
    assert not [r for r in caplog.records if "rebuilt" in r.getMessage()]


class TooFastModel(StandInModel):
    """Claims 1 s to a target whose Dubins time is 100 s."""

    def answer(
        self, targets: Sequence[tuple[float, float]], cancel: threading.Event | None
    ) -> list[TargetSolution]:
        return [
            TargetSolution(1.0, TargetStatus.SOLVED, 1, lp_time=1.0, dubins_time=100.0)
            for _ in targets
        ]


def test_a_model_time_below_the_dubins_time_is_a_logged_defect(
    make_worker: Callable[..., PlannerWorker], caplog: pytest.LogCaptureFixture
) -> None:
    worker = make_worker(TooFastModel)
    assert worker.run(request())
    result = wait_result(worker)
    assert result.defects == len(TARGETS)
    assert "approach model defect: 3 answer(s)" in caplog.text


def test_real_model_answers_pass_the_dubins_check_and_are_counted(
    make_worker: Callable[..., PlannerWorker],
) -> None:
    worker = make_worker()
    assert worker.run(request())
    result = wait_result(worker)
    assert (result.model_times, result.fallback_times, result.defects) == (len(TARGETS), 0, 0)


def test_fallback_and_model_plan_in_the_same_wind() -> None:
    from onboard.planner import approach_model

    assert PLANNABLE_WIND_SHARE == approach_model.PLANNABLE_WIND_SHARE
    limits = AircraftLimits(max_airspeed=22.0)
    wind = Wind(-10.0, 0.0)
    # Flying east at 22 m/s through the air into a 10 m/s headwind: 12 m/s over the ground.
    calm = fallback_time(limits, (0.0, 0.0), (22.0, 0.0), (2400.0, 0.0))
    windy = fallback_time(limits, (0.0, 0.0), (12.0, 0.0), (2400.0, 0.0), wind)
    assert calm == pytest.approx(2400.0 / 22.0)
    assert windy == pytest.approx(2400.0 / 12.0)
    with pytest.raises(ValueError, match="finite"):
        PlanRequest((0.0, 0.0), (12.0, 0.0), ((1.0, 1.0),), 1.0, wind=Wind(math.inf, 0.0))
