"""Asking the planner for the approach times (onboard.approach_plan)."""

from __future__ import annotations

import math

import msgspec
import pytest

from fleet.geo.wind import Wind
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MissionTargets,
    UavResult,
)
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import Telemetry
from onboard.approach_plan import plan_status
from onboard.core import (
    OnboardCore,
)
from onboard.planner.planner_worker import PlanRequest, PlanResult
from tests.onboard.core_harness import (
    TARGETS,
    TWO_TARGETS,
    HeldPlanner,
    Recorder,
    ScriptedPlanner,
    make_core,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


def test_a_stale_plan_is_never_used_for_the_next_mission() -> None:
    planner = HeldPlanner()
    out = Recorder()
    core = OnboardCore(uav_id=112, outputs=out, planner=planner)
    core.on_telemetry(sample_telemetry(), 0.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TWO_TARGETS), 0.0)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=TWO_TARGETS), 0.05)
    first, second = planner.requests
    planner.answer(first, (1.0, 2.0))  # mission 1's answer, same target count
    core.tick(0.1)
    assert out.on(SPACE.mission_result(2, 112)) == []
    planner.answer(second, (7.0, 8.0))
    core.tick(0.2)
    (published,) = out.on(SPACE.mission_result(2, 112))
    assert isinstance(published, UavResult)
    assert (published.mission, published.uav, published.times) == (2, 112, (7.0, 8.0))
    assert (published.model_times, published.fallback_times) == (2, 0)
    # How it flies, for its teammates to time its legs: the request's speed and wind.
    gps = sample_telemetry().gps
    assert gps is not None
    assert (published.lat, published.lon) == (gps.lat, gps.lon)
    # The airspeed is the air data's (the indicated over the root of the density ratio),
    # not the GPS velocity less the wind, which moves with every gust.
    sensor = sample_telemetry().sensor
    assert sensor is not None
    speed = sensor.indicated_airspeed / math.sqrt(sensor.density_ratio)
    assert published.airspeed == pytest.approx(speed, abs=0.01)
    assert planner.requests[1].cruise_speed == pytest.approx(speed)


def test_the_planning_budget_grows_with_the_missions_deadline() -> None:
    core, _ = make_core()
    planner = core.planner
    assert isinstance(planner, ScriptedPlanner)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS, deadline_s=3.0), 0.0)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=TARGETS, deadline_s=30.0), 1.0)
    assert [r.budget_s for r in planner.requests] == [2.0, 15.0]


def windy_core(**sensor: float) -> tuple[OnboardCore, ScriptedPlanner, Telemetry, Telemetry]:
    """A core, its planner, the sample telemetry, and that telemetry in a wind of 6 m/s
    toward the east (wind_west = -6) and 2 toward the north (wind_south = -2), its air
    data changed by `sensor`."""
    planner = ScriptedPlanner((80.0, 40.0, 60.0))
    core = OnboardCore(uav_id=112, outputs=Recorder(), planner=planner)
    telemetry = sample_telemetry()
    assert telemetry.gps is not None and telemetry.sensor is not None
    windy = msgspec.structs.replace(
        telemetry,
        sensor=msgspec.structs.replace(telemetry.sensor, wind_south=-2.0, wind_west=-6.0, **sensor),
    )
    return core, planner, telemetry, windy


def test_the_plan_is_asked_in_the_smoothed_reported_wind() -> None:
    core, planner, telemetry, windy = windy_core()
    core.on_telemetry(windy, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.1)
    # A calm report 2 s later moves the estimate by 1 - exp(-2 / 20) of the way.
    core.on_telemetry(telemetry, 2.0)
    core.on_targets(MissionTargets(mission=2, team=(112,), targets=TARGETS), 2.1)
    first, second = planner.requests
    assert first.wind == Wind(east=6.0, north=2.0)
    # The airspeed held is the air data's (22 m/s indicated at sea level), not the
    # ground velocity less a wind estimate.
    assert first.cruise_speed == pytest.approx(22.0)
    kept = math.exp(-2.0 / 20.0)
    assert second.wind.east == pytest.approx(6.0 * kept)
    assert second.wind.north == pytest.approx(2.0 * kept)


def test_the_plan_is_asked_at_the_air_data_s_airspeed_averaged_like_the_wind() -> None:
    """A gust reads 25 m/s for an instant on an aircraft holding 22 (its air data at sea
    level): the plan, and the result its teammates time its legs by, take the airspeed
    averaged over the wind's time constant, not that instant's reading."""
    core, planner, telemetry, gusty = windy_core(indicated_airspeed=25.0)
    core.on_telemetry(telemetry, 0.0)
    core.on_telemetry(gusty, 2.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 2.1)
    (request,) = planner.requests
    assert request.cruise_speed == pytest.approx(22.0 + 3.0 * (1.0 - math.exp(-2.0 / 20.0)))


def test_without_air_data_the_airspeed_is_the_ground_velocity_less_the_wind() -> None:
    core, planner, _, no_pitot = windy_core(indicated_airspeed=0.0)
    core.on_telemetry(no_pitot, 0.0)
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), 0.1)
    (request,) = planner.requests
    # The ground velocity (21.5 east, 3 north) less the wind (6 east, 2 north).
    assert request.cruise_speed == pytest.approx(math.hypot(15.5, 1.0))


def test_the_status_says_the_wind_planned_in() -> None:
    request = PlanRequest((0.0, 0.0), (22.0, 0.0), ((1.0, 1.0),), 2.0, wind=Wind(east=10.0))
    result = PlanResult(request, (1.0,), (False,), 0.05, 0.01)
    kind, text = plan_status(result, 3)
    assert kind is StatusKind.APPROACH_TIMES
    assert text.endswith("; in a wind from 270 deg at 10.0 m/s")  # a westerly
    calm = PlanResult(
        PlanRequest((0.0, 0.0), (22.0, 0.0), ((1.0, 1.0),), 2.0), (1.0,), (False,), 0.05
    )
    assert "wind" not in plan_status(calm, 3)[1]
