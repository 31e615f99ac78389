"""No-fly zones end to end: the simulator over a real serial link (socket://) logging
incursions from its own positions (`fleet sim --no-fly`), the onboard module as its own
process, a real Zenoh router, and the real `ground-cli send-targets --no-fly`."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from fleet.geo.zones import point_in_ring
from fleet.mission.phase import Phase
from tests.conftest import Ground
from tests.onboard.test_no_fly_in_memory import AROUND_START, files_for, local_fix, zone, zone_of
from tests.support.processes import Fleet
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

CLI_TIMEOUT_S = 120.0


def send(ground: Ground, targets: Path, zones: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable, "-m", "ground.cli", "--connect", ground.router, "send-targets",
            str(targets), "--no-fly", str(zones), "--team", "112", "--wait", "--json",
        ],
        capture_output=True, text=True, timeout=CLI_TIMEOUT_S, check=False,
    )  # fmt: skip


def fly_with(
    fleet: Fleet,
    ground: Ground,
    tmp_path: Path,
    where: tuple[tuple[int, int], ...],
    name: str,
    speedup: float = 10.0,
    before_onboard: Callable[[], None] = lambda: None,
) -> subprocess.CompletedProcess[str]:
    """UAV 112 simulated with one zone at `where`, its onboard up and heard, the mission
    sent with that zone: `ground-cli send-targets --wait`'s answer (it exited 0)."""
    targets, zones = files_for(tmp_path, (zone(where, name),))
    endpoints = fleet.sim("single_uav", speedup, 5.0, "--no-fly", str(zones))
    before_onboard()
    fleet.onboard(112, endpoints[112], ground.router)
    wait_until(lambda: 112 in ground.seen.telemetry, 30.0, "telemetry from UAV 112")
    done = send(ground, targets, zones)
    assert done.returncode == 0, done.stderr
    return done


# A target behind a zone reached with no incursion, an aircraft inside a zone an error on
# the ground and in the simulator's log, no fix inside a zone after the last target: in
# memory, tests/onboard/test_no_fly_in_memory.py.


def test_an_aircraft_inside_a_zone_leaves_it_by_the_shortest_way_and_flies_its_target(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    # Slow, so that it is still deep inside the zone when the mission arrives.
    done = fly_with(fleet, ground, tmp_path, AROUND_START, "start", speedup=2.0)
    seen = ground.seen
    report = json.loads(done.stdout)
    assert report["agreed"] is True
    assert {s["state"] for s in report["target_states"]} == {"assigned"}  # still offered
    ring = zone_of(AROUND_START)
    with seen.lock:
        start = local_fix(seen.telemetry[112][-1])
    assert point_in_ring(start, ring)

    def first_fix_outside() -> tuple[float, float] | None:
        with seen.lock:
            fixes = [local_fix(t) for t in seen.telemetry[112]]
        return next((f for f in fixes if not point_in_ring(f, ring)), None)

    wait_until(lambda: first_fix_outside() is not None, 120.0, "the aircraft out of the zone")
    out = first_fix_outside()
    assert out is not None
    # The target lies east-south-east, through the zone's east edge 800 m on; the shortest
    # ways out are its north and south edges, 300 m either side of the start's line.
    assert abs(out[1]) > 300.0 - 30.0 and out[0] < -1200.0, out
    wait_until(
        lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(112)),
        240.0,
        "target reached",
    )
