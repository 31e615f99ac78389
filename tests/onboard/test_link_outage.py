"""A serial outage right at the commitment, end to end: the target writes are retried
across it and confirmed by the autopilot's echo once the link is back; the UAV reaches
its target and never reports the mission failed."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from fleet.launch.launcher import ring_scenario
from fleet.mission.messages import MissionTargets
from onboard.core import CONFIRM_LIMIT_S, LINK_LOST_S, TARGET_WAYPOINT
from tests.conftest import Ground
from tests.onboard.test_multi_uav import wait_for_telemetry
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.tcp_proxy import cuttable_proxy
from tests.support.waiting import wait_until

#: Longer than the old give-up (4 attempts, 2 s) and than LINK_LOST_S; shorter than
#: the limit after which the target is given up.
OUTAGE_S = 8.0


def test_target_writes_are_retried_across_a_serial_outage_at_the_commitment(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    assert LINK_LOST_S < OUTAGE_S < CONFIRM_LIMIT_S
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(1))
    ((uav, where),) = fleet.sim(str(scenario), 2.0, 5.0).items()
    seen = ground.seen
    with cuttable_proxy(where.program) as proxy:
        fleet.onboard(uav, replace(where, program=proxy.url), ground.router)
        wait_for_telemetry(ground, [uav])
        targets = ring_targets(1, seed=4)
        ground.send(MissionTargets(mission=1, team=(uav,), targets=targets))
        proxy.cut()  # the fault: the link drops as the UAV plans and commits
        wait_until(lambda: uav in seen.assignments, 30.0, "the commitment")
        assert seen.latest_track(uav) != TARGET_WAYPOINT  # not echoed: the link is down
        # The outage lasts until the module has seen it (LINK_LOST_S without telemetry),
        # well within the confirm limit; the module keeps retrying meanwhile.
        wait_until(
            lambda: any("autopilot link lost" in s for s in seen.statuses(uav)),
            OUTAGE_S,
            "the outage seen by the module",
        )
        proxy.restore()
        wait_until(
            lambda: any("flying to target 0" in s for s in seen.statuses(uav)),
            60.0,
            "flying once the echo arrives",
        )
        wait_until(
            lambda: any("reached target 0" in s for s in seen.statuses(uav)), 120.0, "reached"
        )
    statuses = seen.statuses(uav)
    assert any("autopilot link lost" in s for s in statuses)  # the outage was seen
    assert not any("cannot fly" in s or "not confirmed" in s for s in statuses), statuses
    target = targets[0]
    assert seen.closest_approach(uav, target.lat, target.lon) <= 75.0
