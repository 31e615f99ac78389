"""`fleet foxglove`'s drawing of the fleet (ground.foxglove_live.map_layers): the fixes,
the mission as the fleet reports it, and its GeoJSON."""

from __future__ import annotations

import json
import math
from typing import Any

import msgspec
import pytest

from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    Target,
    TargetOutcome,
)
from fleet.mission.phase import Phase
from fleet.recording import channels
from ground.foxglove_live import map_layers
from ground.foxglove_live.map_layers import MissionMap, colour_of, fix_of
from tests.support.link_samples import sample_telemetry

T_NS = 1_700_000_000_123_456_789
TARGETS = (Target(42.36, -71.09, 120.0), Target(42.365, -71.10, 110.0), Target(42.37, -71.08, 90.0))


def telemetry_json(**changes: Any) -> dict[str, Any]:
    value: dict[str, Any] = msgspec.to_builtins(sample_telemetry())
    value.update(changes)
    return value


def report(uav: int, target: int | None, mission: int = 3, epoch: int = 0) -> AssignmentReport:
    pairs = {} if target is None else {uav: target}
    return AssignmentReport(mission, uav, target, pairs, (), (74, 112), "d", epoch=epoch)


def mission_map(mission: int = 3) -> MissionMap:
    view = MissionMap()
    view.on_targets(MissionTargets(mission, (74, 112), TARGETS))
    return view


# ---- fixes ----------------------------------------------------------------------------------
def test_a_fix_is_the_recorders_fix_with_heading_and_colour() -> None:
    value = telemetry_json()
    fix = fix_of(value, 74, T_NS)
    assert fix is not None
    recorded = channels.location_fix(value, 74, T_NS)
    assert recorded is not None
    assert (fix.latitude, fix.longitude, fix.altitude) == (42.36, -71.09, 120.5)
    assert (fix.latitude, fix.longitude, fix.altitude) == (
        recorded["latitude"],
        recorded["longitude"],
        recorded["altitude"],
    )
    assert fix.frame_id == recorded["frame_id"] == "uav74"
    assert fix.time_ns == T_NS
    assert fix.heading_rad == pytest.approx(math.radians(82.0))
    assert fix.colour == colour_of(74)


def test_heading_is_within_one_turn_and_absent_without_attitude() -> None:
    west = telemetry_json(sensor={**telemetry_json()["sensor"], "yaw": -90.0})
    fix = fix_of(west, 7, T_NS)
    assert fix is not None and fix.heading_rad == pytest.approx(math.radians(270.0))
    fix = fix_of(telemetry_json(sensor=None), 7, T_NS)
    assert fix is not None and fix.heading_rad is None
    bad_yaw = telemetry_json(sensor={"yaw": "north"})
    fix = fix_of(bad_yaw, 7, T_NS)
    assert fix is not None and fix.heading_rad is None


@pytest.mark.parametrize(
    "value",
    [
        telemetry_json(gps=None),
        telemetry_json(gps={"lat": 91.0, "lon": 0.0, "alt": 0.0}),
        telemetry_json(gps={"lat": 0.0, "lon": -181.0, "alt": 0.0}),
        telemetry_json(gps={"lat": 0.0, "lon": 0.0, "alt": "high"}),
        telemetry_json(gps={"lat": float("nan"), "lon": 0.0, "alt": 0.0}),
        telemetry_json(gps={"lat": 0.0, "lon": 0.0, "alt": float("inf")}),
        [1, 2, 3],
        "telemetry",
    ],
)
def test_no_fix_without_a_position_on_the_globe(value: object) -> None:
    assert fix_of(value, 7, T_NS) is None


def test_colours_are_the_pages_golden_angle_hues() -> None:
    # ground/gui/static/app.js: hsl((uav * 137.508) % 360, 75%, 38%)
    assert colour_of(74).hex == "#53aa18"  # hue 95.6: green
    assert colour_of(112).hex == "#7b18aa"  # hue 280.9: purple
    assert colour_of(74) != colour_of(75)
    assert all(0.0 <= c <= 1.0 for c in (colour_of(9).r, colour_of(9).g, colour_of(9).b))


# ---- the mission ----------------------------------------------------------------------------
def test_a_newer_mission_starts_afresh_and_an_older_one_is_ignored() -> None:
    view = mission_map(3)
    assert view.on_assignment(report(74, 0))
    assert view.target_of(74) == 0
    assert not view.on_targets(MissionTargets(2, (74,), TARGETS[:1]))
    assert view.mission == 3
    assert not view.on_targets(MissionTargets(3, (74, 112), TARGETS))  # heard again
    assert view.on_targets(MissionTargets(4, (74,), TARGETS[:1]))
    assert view.mission == 4 and view.assigned == {}


def test_reports_of_another_mission_or_an_older_epoch_change_nothing() -> None:
    view = mission_map(3)
    assert not view.on_assignment(report(74, 0, mission=2))
    assert view.on_assignment(report(74, 0, epoch=1))
    assert not view.on_assignment(report(74, 1, epoch=0))  # late consensus report
    assert view.target_of(74) == 0
    assert not view.on_assignment(report(74, 0, epoch=1))  # the same again
    assert view.on_assignment(report(74, 2, epoch=2))  # re-planned
    assert view.target_of(74) == 2


def test_a_uav_that_failed_or_was_aborted_flies_to_no_target() -> None:
    view = mission_map(3)
    for uav, target in ((74, 0), (112, 1), (9, 2)):
        view.on_assignment(report(uav, target))
    assert view.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "too far"))
    assert not view.on_outcome(TargetOutcome(3, 112, 1, Phase.FAILED, "too far"))
    assert view.on_abort(MissionAbort(3, uav=9))
    assert not view.on_abort(MissionAbort(2))
    assert (view.target_of(74), view.target_of(112), view.target_of(9)) == (0, None, None)
    assert view.on_abort(MissionAbort(3))
    assert view.target_of(74) is None


# ---- GeoJSON --------------------------------------------------------------------------------
def features(view: MissionMap) -> list[dict[str, Any]]:
    collection = json.loads(map_layers.geojson(view))
    assert collection["type"] == "FeatureCollection"
    found: list[dict[str, Any]] = collection["features"]
    return found


def test_no_mission_draws_nothing() -> None:
    assert features(MissionMap()) == []


def test_targets_are_points_at_lon_lat_with_who_flies_to_them() -> None:
    view = mission_map(3)
    view.on_assignment(report(74, 0))
    view.on_assignment(report(112, 1))
    view.on_outcome(TargetOutcome(3, 112, 1, Phase.REACHED))
    points = [f for f in features(view) if f["geometry"]["type"] == "Point"]
    assert [f["geometry"]["coordinates"] for f in points] == [[t.lon, t.lat] for t in TARGETS]
    states = [(f["properties"]["state"], f["properties"]["uav"]) for f in points]
    assert states == [("assigned", 74), ("reached", 112), ("unassigned", None)]
    assert points[0]["properties"]["style"]["color"] == colour_of(74).hex
    assert points[0]["properties"]["name"] == "target 0 (mission 3): assigned to UAV 74"
    assert points[1]["properties"]["style"]["color"] == map_layers.REACHED_COLOUR
    assert points[2]["properties"]["alt"] == 90.0


def test_a_line_joins_each_uav_still_flying_to_its_target() -> None:
    view = mission_map(3)
    view.on_assignment(report(74, 0))
    view.on_assignment(report(112, 1))
    view.on_assignment(report(9, 2))
    fix = fix_of(telemetry_json(), 74, T_NS)
    assert fix is not None
    view.on_fix(fix)
    lines = [f for f in features(view) if f["geometry"]["type"] == "LineString"]
    # 112 and 9 have no position yet: no line.
    assert [f["properties"]["uav"] for f in lines] == [74]
    target = [TARGETS[0].lon, TARGETS[0].lat]
    assert lines[0]["geometry"]["coordinates"] == [[-71.09, 42.36], target]
    view.on_outcome(TargetOutcome(3, 74, 0, Phase.REACHED))
    assert not [f for f in features(view) if f["geometry"]["type"] == "LineString"]


def test_a_report_naming_a_target_the_mission_lacks_draws_no_line() -> None:
    view = mission_map(3)
    view.assigned[74] = (0, 42)  # as a hostile report could say, unchecked
    fix = fix_of(telemetry_json(), 74, T_NS)
    assert fix is not None
    view.on_fix(fix)
    assert [f["geometry"]["type"] for f in features(view)] == ["Point"] * 3


def test_another_layer_is_one_more_function() -> None:
    def team_label(view: MissionMap) -> list[dict[str, Any]]:
        return [{"type": "Feature", "geometry": None, "properties": {"team": list(view.assigned)}}]

    view = mission_map(3)
    view.on_assignment(report(74, 0))
    drawn = json.loads(map_layers.geojson(view, (*map_layers.LAYERS, team_label)))["features"]
    assert drawn[-1]["properties"]["team"] == [74]
    assert len(drawn) == len(TARGETS) + 1


def test_a_queue_is_a_tour_and_its_reached_targets_stay_reached() -> None:
    """UAV 74 queues targets 0 then 2. Its tour is drawn through the rest of
    its queue; once it reached 0 (its latest outcome names 0, then 2's outcome lists
    both), 0 stays reached, by 74, and its line goes to 2."""
    view = mission_map(3)
    queues = {74: (0, 2), 112: (1,)}
    for uav in (74, 112):
        view.on_assignment(
            AssignmentReport(3, uav, queues[uav][0], {74: 0, 112: 1}, (), (74, 112), "d",
                             queues=queues)
        )  # fmt: skip
    fix = fix_of(telemetry_json(), 74, T_NS)
    assert fix is not None
    view.on_fix(fix)
    tours = [f for f in features(view) if f["properties"].get("tour")]
    assert [(f["properties"]["uav"], f["properties"]["tour"]) for f in tours] == [(74, [0, 2])]
    points = [f for f in features(view) if f["geometry"]["type"] == "Point"]
    assert [(f["properties"]["state"], f["properties"]["uav"]) for f in points] == [
        ("assigned", 74),
        ("assigned", 112),
        ("assigned", 74),
    ]
    view.on_outcome(TargetOutcome(3, 74, 0, Phase.REACHED, reached={0: 74}))
    lines = [f for f in features(view) if f["geometry"]["type"] == "LineString"]
    assert [(f["properties"]["uav"], f["properties"].get("target")) for f in lines] == [(74, 2)]
    view.on_outcome(TargetOutcome(3, 74, 2, Phase.REACHED, reached={0: 74, 2: 74}))
    points = [f for f in features(view) if f["geometry"]["type"] == "Point"]
    states = [(f["properties"]["state"], f["properties"]["uav"]) for f in points]
    assert states == [("reached", 74), ("assigned", 112), ("reached", 74)]
