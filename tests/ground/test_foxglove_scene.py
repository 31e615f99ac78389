"""The fleet in Foxglove's 3D panel (foxglove.SceneUpdate) and its status texts as Logs."""

from __future__ import annotations

import math

import pytest
from foxglove.messages import LogLevel

from fleet.mission.messages import AssignmentReport, MissionTargets, NoFlyZone, Target
from ground.foxglove_live.map_layers import Fix, MissionMap, colour_of
from ground.foxglove_live.scene import Scene, ShapeKind, log_level, status_log

T_NS = 1_700_000_000_123_456_789
TARGETS = (Target(42.36, -71.09, 120.0), Target(42.365, -71.10, 110.0), Target(42.37, -71.08, 90.0))
ZONE = NoFlyZone(((42.361, -71.095), (42.362, -71.095), (42.362, -71.094), (42.361, -71.095)), "x")


def fix(uav: int, lat: float, lon: float, heading_deg: float) -> Fix:
    return Fix(uav, T_NS, f"uav{uav}", lat, lon, 150.0, math.radians(heading_deg), colour_of(uav))


def mission_view() -> MissionMap:
    view = MissionMap()
    view.on_targets(MissionTargets(3, (74, 112), TARGETS, zones=(ZONE,)))
    queues = {74: (0, 2), 112: (1,)}
    for uav in (74, 112):
        report = AssignmentReport(
            3, uav, queues[uav][0], {74: 0, 112: 1}, (), (74, 112), "d", queues=queues
        )
        view.on_assignment(report)
    view.on_fix(fix(74, 42.36, -71.09, 90.0))
    view.on_fix(fix(112, 42.366, -71.10, 0.0))
    return view


def test_the_scene_has_aircraft_targets_tours_and_zones_in_one_frame() -> None:
    shapes = Scene().shapes(mission_view())
    assert shapes is not None
    found = {shape.entity_id: shape for shape in shapes}
    assert set(found) == {
        "uav/74", "uav/112", "target/3/0", "target/3/1", "target/3/2",
        "tour/74", "tour/112", "zone/3/0",
    }  # fmt: skip
    # The origin is the first UAV's position, at its altitude; its heading and colour.
    uav = found["uav/74"]
    assert uav.kind is ShapeKind.UAV and uav.label == "UAV 74"
    assert uav.points[0] == pytest.approx((0.0, 0.0, 150.0))
    assert uav.heading_rad == pytest.approx(math.pi / 2) and uav.colour == colour_of(74)
    # UAV 112 is north-west of it, about 555 m north.
    x, y, _ = found["uav/112"].points[0]
    assert x < 0 and y == pytest.approx(666.0, rel=0.01)
    # Targets by state: each coloured by the UAV that flies to it.
    assert found["target/3/2"].colour == colour_of(74)
    assert found["target/3/2"].points[0][2] == 90.0
    # UAV 74's tour: from it through targets 0 then 2.
    assert len(found["tour/74"].points) == 3
    zone = found["zone/3/0"]
    assert zone.label == "x" and len(zone.points) == 4 and zone.points[0][2] == 150.0


def test_the_sdk_s_scene_update_encodes_and_nothing_places_no_scene() -> None:
    update = Scene().update(mission_view(), T_NS)
    assert update is not None and len(update.encode()) > 500
    assert Scene().update(MissionMap(), T_NS) is None


def test_a_status_text_is_a_log_at_its_severity() -> None:
    assert log_level({"text": "GPS degraded", "severity": "warning"}) == LogLevel.Warning
    assert log_level({"text": "lost", "severity": "error"}) == LogLevel.Error
    assert log_level({"text": "module on"}) == LogLevel.Info
    assert log_level({"severity": "info"}) is None and log_level("text") is None
    log = status_log({"text": "module on"}, 112, T_NS)
    assert log is not None and log.encode()
