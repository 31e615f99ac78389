"""No-fly zones flown in the test's process: the real onboard process logic and the
simulated autopilot (its own record of incursions, `fleet.sim.zone_log`, logged from
every integration step) on in-memory links and the in-process bus
(tests/support/memory_world.py), and the real `ground-cli send-targets --no-fly` run by
its root on that bus. An aircraft still deep inside a zone when `--wait` answers needs
a slow simulation, so a long test: tests/onboard/test_no_fly_e2e.py."""

from __future__ import annotations

import itertools
import json
import logging
import math
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
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
from tests.support.ground_cli import ground_cli_here
from tests.support.ground_view import GroundView
from tests.support.memory_world import MemoryFleet, memory_fleet
from tests.support.waiting import wait_until

UAV = 112

#: The single-UAV scenario's local plane: 112 starts at (-2000, 0) flying east at 22 m/s;
#: its target 1 is at (-68, -518).
PLANE = MercatorProjection(35.72, -120.765)
#: A box across the straight line from the start to target 1, and across the course.
BETWEEN = ((-800, -700), (-400, -700), (-400, 100), (-800, 100))
#: A box around the start: the aircraft is inside it when the mission arrives.
AROUND_START = ((-2600, -300), (-1200, -300), (-1200, 300), (-2600, 300))
#: Between target 1 and the course's waypoint 0 (1000, 0), clear of the course's own
#: legs (y = 0, x = 1000, y = -1000) and of the straight line from the start to target 1:
#: only the way back to the course after the target crosses it.
AFTER_TARGET = ((250, -600), (700, -600), (700, -150), (250, -150))
#: How far the aircraft flies after its last target before the log is read (m).
AFTER_FLIGHT_M = 4000.0


def zone(corners: tuple[tuple[int, int], ...], name: str) -> NoFlyZone:
    return NoFlyZone(ring=tuple(PLANE.to_latlon(x, y) for x, y in corners), name=name)


def zone_of(corners: tuple[tuple[int, int], ...]) -> tuple[tuple[float, float], ...]:
    return tuple((float(x), float(y)) for x, y in corners)


def local_fix(t: Telemetry) -> tuple[float, float]:
    assert t.gps is not None
    return PLANE.to_xy(t.gps.lat, t.gps.lon)


def files_for(tmp_path: Path, zones: tuple[NoFlyZone, ...]) -> tuple[Path, Path]:
    targets = read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin"))
    targets_path, zones_path = tmp_path / "target.bin", tmp_path / "zones.geojson"
    write_targets(targets_path, targets[1:2])
    zones_path.write_bytes(encode_zones(zones))
    return targets_path, zones_path


@contextmanager
def fly_with(
    tmp_path: Path, where: tuple[tuple[int, int], ...], name: str, speedup: float
) -> Iterator[tuple[MemoryFleet, GroundView, subprocess.CompletedProcess[str]]]:
    """UAV 112 simulated with one zone at `where`, heard from its start, the mission sent
    with that zone: the fleet, what the ground sees and `ground-cli send-targets --wait`'s
    answer (it exited 0)."""
    the_zone = zone(where, name)
    targets, zones = files_for(tmp_path, (the_zone,))
    with memory_fleet("single_uav", speedup=speedup, zones=(the_zone,), ready=False) as fleet:
        seen = GroundView.on_bus(fleet.bus())
        try:
            wait_until(lambda: UAV in seen.telemetry, 30.0, "telemetry from UAV 112")
            done = ground_cli_here(
                "send-targets", str(targets), "--no-fly", str(zones),
                "--team", str(UAV), "--wait", "--json",
                connect=fleet.spec,
            )  # fmt: skip
            assert done.returncode == 0, done.stderr
            yield fleet, seen, done
        finally:
            seen.close()


def entries(caplog: pytest.LogCaptureFixture) -> list[str]:
    """The simulator's log of entries into a zone."""
    return [m for m in caplog.messages if f"UAV {UAV} entered no-fly zone" in m]


def test_a_target_behind_a_zone_is_reached_with_no_incursion(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="fleet.sim")
    with fly_with(tmp_path, BETWEEN, "between", speedup=20.0) as (fleet, seen, done):
        assert json.loads(done.stdout)["agreed"] is True
        assert any("1 routed around no-fly zones" in s for s in seen.statuses(UAV))
        wait_until(
            lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(UAV)),
            120.0,
            "target reached",
        )
        flown = seen.tracks[UAV]
        assert ROUTE_WAYPOINTS[0] in flown and TARGET_WAYPOINT in flown
        assert flown.index(ROUTE_WAYPOINTS[0]) < flown.index(TARGET_WAYPOINT)
        # The simulator's own account, from every integration step of the flight.
        assert fleet.aircraft[UAV].autopilot.zone_log.incursions == 0
    assert not entries(caplog), entries(caplog)


def test_an_aircraft_inside_a_zone_is_an_error_on_the_ground_and_in_the_simulator_log(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="fleet.sim")
    with fly_with(tmp_path, AROUND_START, "start", speedup=10.0) as (_, seen, _):
        assert any("entered no-fly zone 0 (start)" in m for m in entries(caplog)), entries(caplog)

        def incursions() -> list[str]:
            return [
                m.text
                for m in seen.status_messages.get(UAV, [])
                if m.kind is StatusKind.ZONE_INCURSION and m.severity is Severity.ERROR
            ]

        wait_until(lambda: bool(incursions()), 30.0, "the incursion error")
        assert "inside no-fly zone 0 (start)" in incursions()[0]


def test_after_its_last_target_the_aircraft_loiters_with_no_fix_inside_a_zone(
    tmp_path: Path,
) -> None:
    with fly_with(tmp_path, AFTER_TARGET, "after", speedup=60.0) as (fleet, seen, _):
        wait_until(
            lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(UAV)),
            120.0,
            "target reached",
        )
        with seen.lock:
            after = len(seen.telemetry[UAV])

        def flown_since() -> float:
            with seen.lock:
                fixes = [local_fix(t) for t in seen.telemetry[UAV][after:]]
            return sum(math.dist(a, b) for a, b in itertools.pairwise(fixes))

        # What happens after the last target, for as long as the way back to the course
        # would take twice over: an observed distance flown, not a time.
        wait_until(lambda: flown_since() >= AFTER_FLIGHT_M, 120.0, "4 km flown after the target")
        with seen.lock:
            fixes = [local_fix(t) for t in seen.telemetry[UAV][after:]]
        ring = zone_of(AFTER_TARGET)
        inside = [fix for fix in fixes if point_in_ring(fix, ring)]
        assert not inside, f"{len(inside)} fixes inside the zone after the target: {inside[:3]}"
        assert set(seen.tracks[UAV][-4:]) <= set(LOITER_WAYPOINTS)  # it waits, loitering
        # The simulator's own account, from every integration step of the flight.
        assert fleet.aircraft[UAV].autopilot.zone_log.incursions == 0
