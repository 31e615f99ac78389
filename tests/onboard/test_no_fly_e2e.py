"""No-fly zones end to end: the simulator over a real serial link (socket://) logging
incursions from its own positions (`fleet sim --no-fly`), the onboard module as its own
process, a real Zenoh router, and the real `ground-cli send-targets --no-fly`."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
from collections.abc import Callable
from importlib.resources import files
from pathlib import Path

import pytest

from fleet.files.targets_io import read_targets, write_targets
from fleet.files.zones_file import encode_zones
from fleet.geo.mercator import MercatorProjection
from fleet.geo.zones import point_in_ring
from fleet.mission.messages import NoFlyZone
from fleet.mission.phase import Phase, Severity
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import Telemetry
from onboard.loiter import LOITER_WAYPOINTS
from onboard.route_flight import ROUTE_WAYPOINTS
from onboard.target_flight import TARGET_WAYPOINT
from tests.conftest import Ground
from tests.support.processes import Child, Fleet
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

#: The single-UAV scenario's local plane: 112 starts at (-2000, 0) flying east at 22 m/s;
#: its target 1 is at (-68, -518).
PLANE = MercatorProjection(35.72, -120.765)
#: A box across the straight line from the start to target 1, and across the course.
BETWEEN = ((-800, -700), (-400, -700), (-400, 100), (-800, 100))
#: A box around the start: the aircraft is inside it when the mission arrives.
AROUND_START = ((-2600, -300), (-1200, -300), (-1200, 300), (-2600, 300))
CLI_TIMEOUT_S = 120.0


def zone(corners: tuple[tuple[int, int], ...], name: str) -> NoFlyZone:
    return NoFlyZone(ring=tuple(PLANE.to_latlon(x, y) for x, y in corners), name=name)


def files_for(tmp_path: Path, zones: tuple[NoFlyZone, ...]) -> tuple[Path, Path]:
    targets = read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin"))
    targets_path, zones_path = tmp_path / "target.bin", tmp_path / "zones.geojson"
    write_targets(targets_path, targets[1:2])
    zones_path.write_bytes(encode_zones(zones))
    return targets_path, zones_path


def send(ground: Ground, targets: Path, zones: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            sys.executable, "-m", "ground.cli", "--connect", ground.router, "send-targets",
            str(targets), "--no-fly", str(zones), "--team", "112", "--wait", "--json",
        ],
        capture_output=True, text=True, timeout=CLI_TIMEOUT_S, check=False,
    )  # fmt: skip


def sim_child(fleet: Fleet) -> Child:
    return next(c for c in fleet.children if c.name == "fleet sim")


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


def test_a_target_behind_a_zone_is_reached_with_no_incursion(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    done = fly_with(fleet, ground, tmp_path, BETWEEN, "between")
    seen = ground.seen
    assert json.loads(done.stdout)["agreed"] is True
    assert any("1 routed around no-fly zones" in s for s in seen.statuses(112))
    wait_until(
        lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(112)),
        120.0,
        "target reached",
    )
    flown = seen.tracks[112]
    assert ROUTE_WAYPOINTS[0] in flown and TARGET_WAYPOINT in flown
    assert flown.index(ROUTE_WAYPOINTS[0]) < flown.index(TARGET_WAYPOINT)
    # The simulator's own account, from every integration step of the flight.
    sim = sim_child(fleet)
    assert sim.stop() == 0
    assert "no-fly incursions: UAV 112: 0" in "\n".join(sim.history)
    assert not any("entered no-fly zone" in line for line in sim.history)


def test_an_aircraft_inside_a_zone_is_an_error_on_the_ground_and_in_the_simulator_log(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    def entered() -> None:
        line = "UAV 112 entered no-fly zone 0 (start)"
        sim_child(fleet).wait_for_line(lambda s: line in s, 30.0)

    fly_with(fleet, ground, tmp_path, AROUND_START, "start", before_onboard=entered)
    seen = ground.seen

    def incursions() -> list[str]:
        return [
            m.text
            for m in seen.status_messages.get(112, [])
            if m.kind is StatusKind.ZONE_INCURSION and m.severity is Severity.ERROR
        ]

    wait_until(lambda: bool(incursions()), 30.0, "the incursion error")
    assert "inside no-fly zone 0 (start)" in incursions()[0]


#: Between target 1 and the course's waypoint 0 (1000, 0), clear of the course's own
#: legs (y = 0, x = 1000, y = -1000) and of the straight line from the start to target 1:
#: only the way back to the course after the target crosses it.
AFTER_TARGET = ((250, -600), (700, -600), (700, -150), (250, -150))
#: How far the aircraft flies after its last target before the log is read (m).
AFTER_FLIGHT_M = 4000.0


def zone_of(corners: tuple[tuple[int, int], ...]) -> tuple[tuple[float, float], ...]:
    return tuple((float(x), float(y)) for x, y in corners)


def local_fix(t: Telemetry) -> tuple[float, float]:
    assert t.gps is not None
    return PLANE.to_xy(t.gps.lat, t.gps.lon)


def test_after_its_last_target_the_aircraft_loiters_with_no_fix_inside_a_zone(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    fly_with(fleet, ground, tmp_path, AFTER_TARGET, "after")
    seen = ground.seen
    wait_until(
        lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(112)),
        120.0,
        "target reached",
    )
    with seen.lock:
        after = len(seen.telemetry[112])

    def flown_since() -> float:
        with seen.lock:
            fixes = [local_fix(t) for t in seen.telemetry[112][after:]]
        return sum(math.dist(a, b) for a, b in itertools.pairwise(fixes))

    # What happens after the last target, for as long as the way back to the course
    # would take twice over: an observed distance flown, not a time.
    wait_until(lambda: flown_since() >= AFTER_FLIGHT_M, 120.0, "4 km flown after the target")
    with seen.lock:
        fixes = [local_fix(t) for t in seen.telemetry[112][after:]]
    ring = zone_of(AFTER_TARGET)
    inside = [fix for fix in fixes if point_in_ring(fix, ring)]
    assert not inside, f"{len(inside)} fixes inside the zone after the target: {inside[:3]}"
    assert set(seen.tracks[112][-4:]) <= set(LOITER_WAYPOINTS)  # it waits, loitering
    # The simulator's own account, from every integration step of the flight.
    sim = sim_child(fleet)
    assert sim.stop() == 0
    assert "no-fly incursions: UAV 112: 0" in "\n".join(sim.history)


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
