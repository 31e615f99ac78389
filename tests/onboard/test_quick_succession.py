"""Two missions 50 ms apart, end to end: the second supersedes the first on every UAV,
atomically; no approach time computed for the first is ever used for the second."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import distance_m
from fleet.mission.messages import MissionTargets, Target
from tests.conftest import Ground
from tests.onboard.test_multi_uav import assert_agreed, start_ring
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

GAP_S = 0.05


def far_targets(count: int) -> tuple[Target, ...]:
    """Targets 8-9 km out: a time computed for a ring target (0.5-2.5 km) is far shorter."""
    near = ring_targets(count, seed=3)
    return tuple(Target(t.lat + 0.075, t.lon, t.alt) for t in near)


@pytest.mark.parametrize("first_count", [3, 2], ids=["equal-counts", "different-counts"])
def test_a_second_mission_50_ms_later_supersedes_the_first_everywhere(
    fleet: Fleet, ground: Ground, tmp_path: Path, first_count: int
) -> None:
    team = start_ring(fleet, ground, tmp_path, 3)
    seen = ground.seen
    first = MissionTargets(mission=1, team=tuple(team), targets=ring_targets(first_count, 5))
    second = MissionTargets(mission=2, team=tuple(team), targets=far_targets(3))
    with seen.lock:
        starts = {uav: seen.telemetry[uav][-1].gps for uav in team}
    ground.send(first)
    time.sleep(GAP_S)  # the fault: the next mission, 50 ms later
    ground.send(second)

    def all_on_second() -> bool:
        with seen.lock:
            reports = dict(seen.assignments)
        return len(reports) == 3 and all(r.mission == 2 for r in reports.values())

    wait_until(all_on_second, 60.0, "every UAV committed mission 2")
    assert_agreed(dict(seen.assignments), set(team), 3)
    top_speed = AircraftLimits().max_airspeed
    for uav in team:
        result = seen.results[uav]
        assert result.mission == 2
        start = starts[uav]
        assert start is not None
        for target, time_s in zip(second.targets, result.times, strict=True):
            assert time_s is not None and math.isfinite(time_s)
            # Never a first-mission time: no aircraft covers the distance faster.
            # (0.7: the aircraft flies on, sped up, for a moment before it plans.)
            floor = distance_m((start.lat, start.lon), (target.lat, target.lon)) / top_speed
            assert time_s >= 0.7 * floor, f"UAV {uav}: {time_s:.0f} s < {floor:.0f} s"


def test_a_new_mission_in_flight_replaces_the_old_target_without_a_false_arrival(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    team = start_ring(fleet, ground, tmp_path, 1)
    (uav,) = team
    seen = ground.seen
    first = MissionTargets(mission=1, team=(uav,), targets=far_targets(1))
    ground.send(first)
    wait_until(
        lambda: any("mission 1: flying to target 0" in s for s in seen.statuses(uav)),
        30.0,
        "flying mission 1's target",
    )
    # The fault: a new mission arrives while the aircraft flies to the old target.
    second = MissionTargets(mission=2, team=(uav,), targets=ring_targets(1, seed=21))
    ground.send(second)
    wait_until(
        lambda: any("mission 2: flying to target 0" in s for s in seen.statuses(uav)),
        30.0,
        "flying mission 2's target",
    )
    statuses = seen.statuses(uav)
    assert not any(s.startswith("reached") for s in statuses), statuses  # 8 km short of it
    assert not any("could not resume" in s for s in statuses), statuses
    assert seen.assignments[uav].mission == 2
