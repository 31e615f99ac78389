"""Each UAV's legs in its own air: its airspeed and wind from its digested result, the
turn over each target timed from the track it came in on; checked against the simulated
aircraft flying the queue."""

from __future__ import annotations

import math
import random

import msgspec
import pytest

from fleet.consensus.assignment import air_bytes, results_digest
from fleet.consensus.legs import (
    ACCEPTANCE_RADIUS_M,
    LEG_SPEED_MPS,
    MEAN_TURN_RADII,
    WIND_SHARE,
    Air,
    AirLegs,
    LegGeometry,
    leg_from_here,
)
from fleet.consensus.mission_round import MissionRound
from fleet.consensus.objectives import plan_queues
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.wind import Wind
from fleet.mission.messages import MissionTargets, Target, UavResult
from fleet.mission.objective import Objective
from fleet.sim.aircraft import AircraftState
from fleet.sim.aircraft import Wind as SimWind
from fleet.sim.guidance import fly_until_arrival

ORIGIN = (35.72, -120.76)
PROJECTION = MercatorProjection(*ORIGIN)


def targets_at(*points: tuple[float, float]) -> list[Target]:
    return [Target(*PROJECTION.to_latlon(x, y), 600.0) for x, y in points]


def test_a_result_says_how_its_uav_flies_and_wild_numbers_are_ignored() -> None:
    plain = UavResult(mission=1, uav=2, times=(1.0,))
    assert Air.of(plain) == Air(LEG_SPEED_MPS, Wind(), None)
    told = msgspec.structs.replace(
        plain, airspeed=25.0, wind_east=3.0, wind_north=-4.0, lat=1.0, lon=2.0
    )
    assert Air.of(told) == Air(25.0, Wind(3.0, -4.0), (1.0, 2.0))
    # A wind nearly as fast as the aircraft is flown in at the share the model plans in.
    gale = msgspec.structs.replace(told, airspeed=20.0, wind_east=30.0, wind_north=0.0)
    assert Air.of(gale).wind.east == pytest.approx(16.0)
    from onboard.planner.approach_model import PLANNABLE_WIND_SHARE

    assert WIND_SHARE == PLANNABLE_WIND_SHARE  # the first target's model's own share
    assert Air.of(msgspec.structs.replace(told, airspeed=1.0)).airspeed == LEG_SPEED_MPS


def test_a_pairwise_leg_in_still_air_is_its_length_plus_the_mean_turn() -> None:
    targets = targets_at((0.0, 0.0), (3000.0, 0.0))
    legs = AirLegs(LegGeometry.of(targets), {7: Air(20.0)})
    radius = AircraftLimits().turn_radius(20.0)
    metres = LegGeometry.of(targets).metres[0][1]
    expected = (metres + MEAN_TURN_RADII * radius - 0.5 * ACCEPTANCE_RADIUS_M) / 20.0
    assert legs.of(7)[0][1] == pytest.approx(expected)
    # A UAV the results say nothing of flies the default air.
    assert legs.of(8)[0][1] == pytest.approx(
        (metres + MEAN_TURN_RADII * AircraftLimits().turn_radius(22.0) - 30.0) / 22.0
    )


def test_upwind_legs_are_slower_than_downwind_and_a_faster_uav_is_faster() -> None:
    targets = targets_at((0.0, 0.0), (4000.0, 0.0))
    westerly = Wind(10.0, 0.0)
    geometry = LegGeometry.of(targets)
    legs = AirLegs(geometry, {1: Air(22.0, westerly), 2: Air(28.0, westerly)})
    east, west = legs.of(1)[0][1], legs.of(1)[1][0]
    metres = geometry.metres[0][1]
    assert east == pytest.approx((metres + 0.5 * AircraftLimits().turn_radius(22) - 30) / 32, 1e-6)
    assert west > 2.5 * east
    assert legs.of(2)[1][0] < west


def test_a_reversal_costs_more_than_flying_on() -> None:
    # Into target 1 from the west, then on east (target 2) or back west (target 0).
    targets = targets_at((0.0, 0.0), (3000.0, 0.0), (6000.0, 0.0))
    geometry = LegGeometry.of(targets)
    legs = AirLegs(geometry, {1: Air(22.0)})
    on = legs.turning_leg(1, 0, 1, 2)
    back = legs.turning_leg(1, 0, 1, 0)
    assert on == pytest.approx(geometry.metres[1][2] / 22.0, rel=1e-6)
    radius = AircraftLimits().turn_radius(22.0)
    assert back - on == pytest.approx((1.1 * radius * math.pi - 2 * ACCEPTANCE_RADIUS_M) / 22, 1e-3)


@pytest.mark.parametrize(
    ("airspeed", "wind"),
    [(22.0, Wind()), (20.0, Wind(10.0, 0.0)), (28.0, Wind(-6.0, 8.0))],
)
def test_every_leg_of_a_queue_is_within_5_percent_of_the_simulated_flight(
    airspeed: float, wind: Wind
) -> None:
    rng = random.Random(f"{airspeed}:{wind}")
    points = [(0.0, 0.0)]
    for _ in range(4):
        distance, bearing = rng.uniform(1500.0, 4000.0), rng.uniform(0.0, math.tau)
        x, y = points[-1]
        points.append((x + distance * math.sin(bearing), y + distance * math.cos(bearing)))
    targets = targets_at(*points[1:])
    legs = AirLegs(LegGeometry.of(targets), {1: Air(airspeed, wind, ORIGIN)})
    state = AircraftState(0.0, 0.0, 600.0, 0.0, airspeed)
    clock, flown = 0.0, []
    for point in points[1:]:
        took, state = fly_until_arrival(
            state, point, wind=SimWind(north=wind.north, east=wind.east), airspeed=airspeed
        )
        clock += took
        flown.append(clock)
    predicted = legs.arrivals(1, flown[0], range(len(targets)))
    for k in range(1, len(flown)):
        leg_flown = flown[k] - flown[k - 1]
        leg_predicted = predicted[k] - predicted[k - 1]
        assert leg_predicted == pytest.approx(leg_flown, rel=0.05), k


def test_a_leg_into_a_wind_of_three_quarters_the_airspeed_is_timed_as_flown() -> None:
    """20 m/s into a 15 m/s headwind (a 15 m/s wind with the slowest aircraft of a mixed
    team): 5 m/s over the ground, not the 6 a cap at 0.7 of the airspeed would say."""
    airspeed, wind = 20.0, Wind(0.0, -15.0)
    points = [(0.0, 0.0), (0.0, 1500.0), (0.0, 3000.0)]
    said = UavResult(1, 1, (1.0, 1.0), airspeed=airspeed, wind_east=wind.east,
                     wind_north=wind.north, lat=ORIGIN[0], lon=ORIGIN[1])  # fmt: skip
    legs = AirLegs(LegGeometry.of(targets_at(*points[1:])), {1: Air.of(said)})
    state = AircraftState(0.0, 0.0, 600.0, 0.0, airspeed)
    flown = []
    for point in points[1:]:
        took, state = fly_until_arrival(
            state, point, wind=SimWind(north=wind.north, east=wind.east), airspeed=airspeed
        )
        flown.append(took)
    predicted = legs.arrivals(1, flown[0], (0, 1))
    assert predicted[1] - predicted[0] == pytest.approx(flown[1], rel=0.05)


def _results(air: bool) -> dict[int, UavResult]:
    rows = {3: (100.0, 300.0, 500.0, 700.0), 5: (400.0, 200.0, 600.0, 150.0)}
    out = {}
    for uav, times in rows.items():
        result = UavResult(mission=9, uav=uav, times=times)
        if air:
            result = msgspec.structs.replace(
                result, airspeed=20.0 + uav, wind_east=10.0, wind_north=1.0, lat=35.7, lon=-120.7
            )
        out[uav] = result
    return out


def _round(results: dict[int, UavResult], own: int) -> MissionRound:
    targets = MissionTargets(
        mission=9,
        team=(3, 5),
        targets=tuple(targets_at((0, 0), (2000, 500), (4000, -1000), (-2000, 3000))),
        objective=Objective.MIN_SUM,
    )
    mission_round = MissionRound(targets=targets, own_id=own, started=0.0)
    for uav in sorted(results, reverse=own == 5):
        assert mission_round.add_result(results[uav])
    return mission_round


def test_every_uav_plans_the_same_queues_and_digest_from_the_same_results() -> None:
    results = _results(air=True)
    first = _round(results, 3).decide({3, 5})
    second = _round(results, 5).decide({3, 5})
    assert first.queues == second.queues
    assert first.arrivals == second.arrivals
    assert first.digest == second.digest
    # The legs are each UAV's own: the same times in still air give other arrivals.
    still = _round(_results(air=False), 3).decide({3, 5})
    assert still.digest != first.digest
    assert still.arrivals != first.arrivals


def test_the_digest_covers_how_each_uav_flies_and_is_unchanged_without_it() -> None:
    times = {3: (1.0, 2.0)}
    assert results_digest(times) == results_digest(times, air={3: air_bytes(3, (None,) * 5)})
    slow = results_digest(times, air={3: air_bytes(3, (20.0, 1.0, 0.0, None, None))})
    fast = results_digest(times, air={3: air_bytes(3, (21.0, 1.0, 0.0, None, None))})
    assert len({results_digest(times), slow, fast}) == 3


def test_the_plan_is_the_same_whatever_order_the_tables_are_asked_in() -> None:
    rng = random.Random(5)
    targets = targets_at(*((rng.uniform(-5e3, 5e3), rng.uniform(-5e3, 5e3)) for _ in range(12)))
    air = {uav: Air(20.0 + uav, Wind(8.0, -3.0), ORIGIN) for uav in (1, 2, 3)}
    times = {uav: [rng.uniform(50.0, 400.0) for _ in targets] for uav in air}
    plans = []
    for objective in (Objective.MIN_SUM, Objective.MIN_MAX, Objective.GREEDY):
        for _ in range(2):
            legs = AirLegs(LegGeometry.of(targets), air)
            plans.append(plan_queues(times, legs, objective))
        assert plans[-1] == plans[-2]


def test_a_leg_from_here_is_timed_in_the_air_of_the_moment_from_the_track_flown_in() -> None:
    """Straight on from target 0 to 1 (3 km east): the length at the ground speed, the
    wind's included; come in heading west, the reversal adds time; no leg to itself or to
    a target the mission does not have."""
    geometry = LegGeometry.of(targets_at((0.0, 0.0), (3000.0, 0.0)))
    metres = geometry.metres[0][1]
    assert leg_from_here(geometry, Air(22.0), (22.0, 0.0), 0, 1) == pytest.approx(metres / 22.0)
    tail = leg_from_here(geometry, Air(22.0, Wind(10.0, 0.0)), (32.0, 0.0), 0, 1)
    assert tail == pytest.approx(metres / 32.0)
    turning = leg_from_here(geometry, Air(22.0), (-22.0, 0.0), 0, 1)
    assert turning is not None and turning > metres / 22.0 + 5.0
    expected = AirLegs(geometry, {1: Air(22.0)}).turning_leg(1, (100.0, 0.0), 0, 1)
    assert turning == pytest.approx(expected)
    # Not moving over the ground: the mean turn (the pairwise leg).
    assert leg_from_here(geometry, Air(22.0), (0.0, 0.0), 0, 1) == pytest.approx(
        AirLegs(geometry, {1: Air(22.0)}).of(1)[0][1]
    )
    assert leg_from_here(geometry, Air(22.0), (22.0, 0.0), 0, 0) is None
    assert leg_from_here(geometry, Air(22.0), (22.0, 0.0), 0, 2) is None
