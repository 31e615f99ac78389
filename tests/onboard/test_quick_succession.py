"""Two missions 50 ms apart, end to end: the second supersedes the first on every UAV,
atomically; no approach time computed for the first is ever used for the second."""

from __future__ import annotations

from pathlib import Path

from fleet.mission.messages import MissionTargets, Target
from tests.conftest import Ground
from tests.onboard.test_multi_uav import start_ring
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

GAP_S = 0.05


def far_targets(count: int) -> tuple[Target, ...]:
    """Targets 8-9 km out: a time computed for a ring target (0.5-2.5 km) is far shorter."""
    near = ring_targets(count, seed=3)
    return tuple(Target(t.lat + 0.075, t.lon, t.alt) for t in near)


# A second mission 50 ms later superseding the first on every UAV: in memory,
# tests/onboard/test_multi_uav_in_memory.py.


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
