"""Scenario files: the shipped scenarios, their targets, and strict, clear validation."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from fleet.consensus.assignment import greedy_assign
from fleet.geo.mercator import MercatorProjection
from fleet.sim import (
    AircraftState,
    Scenario,
    ScenarioError,
    UavSpec,
    fly_to_point,
    load_scenario,
    resolve_scenario,
    shipped_scenario,
    shipped_scenario_names,
    shipped_scenario_path,
)

VALID = """\
description = "test"

[wind]
north = 1.0
east = -2.0

[[uav]]
id = 7
lat = 42.0
lon = -71.0
alt = 300.0
heading = 45.0
airspeed = 20.0
plan = [[42.01, -71.0, 300.0], [42.01, -70.99, 310.0]]
"""


def write(tmp_path: Path, text: str, name: str = "scenario.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def approach_times(scenario: Scenario, uav: UavSpec) -> list[float]:
    """Seconds the simulator's own aircraft and guidance take to each target."""
    projection = MercatorProjection(uav.lat, uav.lon)
    start = AircraftState(0.0, 0.0, uav.alt, math.radians(uav.heading), uav.airspeed)
    return [
        fly_to_point(start, projection.to_xy(t.lat, t.lon), limits=scenario.limits)
        for t in scenario.targets()
    ]


def test_shipped_scenarios_are_found_by_name() -> None:
    assert {"single_uav", "head_on"} <= set(shipped_scenario_names())
    assert shipped_scenario_path("head_on").name == "head_on.toml"
    assert resolve_scenario("head_on") == shipped_scenario("head_on")
    with pytest.raises(ScenarioError, match=r"no shipped scenario 'nowhere'.*head_on"):
        shipped_scenario("nowhere")


def test_single_uav_is_112_flying_east_and_best_target_is_not_the_first() -> None:
    scenario = shipped_scenario("single_uav")
    (uav,) = scenario.uavs
    assert (uav.piccolo_id, uav.heading) == (112, 90.0)
    assert len(scenario.targets()) == 3
    times = approach_times(scenario, uav)
    best = min(range(3), key=times.__getitem__)
    assert best == 1
    # A clear margin: a planner slightly off (a point-mass model) still agrees.
    assert sorted(times)[1] > 1.3 * times[best]
    # No plan: the default racetrack, waypoint 0 three kilometres straight ahead.
    first = uav.waypoints()[0]
    x, y = MercatorProjection(uav.lat, uav.lon).to_xy(first.lat, first.lon)
    assert (x, y) == pytest.approx((3000.0, 0.0), abs=0.01)
    assert [w.next_index for w in uav.waypoints()] == [1, 2, 3, 0]


def test_head_on_has_a_contested_target_and_the_greedy_splits_it() -> None:
    scenario = shipped_scenario("head_on")
    assert [u.piccolo_id for u in scenario.uavs] == [74, 112]
    uav74, uav112 = scenario.uavs
    distance = math.hypot(*MercatorProjection(uav74.lat, uav74.lon).to_xy(uav112.lat, uav112.lon))
    assert 5500.0 < distance < 6500.0
    assert abs(uav74.heading - uav112.heading) == 180.0
    results = {uav.piccolo_id: approach_times(scenario, uav) for uav in scenario.uavs}
    # Target 0 is the best of both UAVs: the assignment is not a trivial one.
    for times in results.values():
        assert min(range(3), key=times.__getitem__) == 0
    assert greedy_assign(results, 3).pairs == {74: 0, 112: 1}
    # Margins for a planner that is somewhat off.
    assert results[112][0] > 1.1 * results[74][0]
    assert results[112][1] > 1.1 * results[112][0]


def test_a_valid_file_loads(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, VALID))
    assert scenario.name == "scenario"
    assert (scenario.wind.north, scenario.wind.east) == (1.0, -2.0)
    (uav,) = scenario.uavs
    assert uav.plan == ((42.01, -71.0, 300.0), (42.01, -70.99, 310.0))
    assert [(w.index, w.next_index) for w in uav.waypoints()] == [(0, 1), (1, 0)]
    assert scenario.targets() == []
    assert resolve_scenario(str(tmp_path / "scenario.toml")) == scenario


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("lat = 42.0", "lat = 95.0", r"uav\[0\]\.lat: expected `float` <= 85\.0"),
        ("lat = 42.0", 'lat = "north"', r"uav\[0\]\.lat: expected `float`, got `str`"),
        ("heading = 45.0", "heading = true", r"uav\[0\]\.heading: expected `float`, got `bool`"),
        ("heading = 45.0", "heading = 360.0", r"uav\[0\]\.heading: expected `float` < 360\.0"),
        ("heading = 45.0", "hedding = 45.0", r"uav\[0\]: object contains unknown field `hedding`"),
        ("airspeed = 20.0", "airspeed = 40.0", r"uav\[0\]\.airspeed: .*\[15, 30\]"),
        ("id = 7", "id = 0", r"uav\[0\]\.id: expected `int` >= 1"),
        ("id = 7\n", "", r"uav\[0\]: object missing required field `id`"),
        ("[[42.01", "[[142.01", r"uav\[0\]\.plan\[0\]\[0\]: expected `float` <= 85\.0"),
        ("-70.99, 310.0]", "-70.99]", r"uav\[0\]\.plan\[1\]: expected `array` of length 3, got 2"),
        ("east = -2.0", "east = -20.0", r"wind: speed 20\.0 m/s must be below"),
        ("east = -2.0", "west = -2.0", r"wind: object contains unknown field `west`"),
        ("east = -2.0", "east = 8.0\ngust = 3.0", r"wind: speed 17\.1 m/s \(mean \+ drift"),
        ("east = -2.0", "gust = -1.0", r"wind\.gust: expected `float` >= 0\.0"),
        ("east = -2.0", "seed = 1.5", r"wind\.seed: expected `int`"),
        ("east = -2.0", "gust_time = 0.0", r"wind\.gust_time: expected `float` > 0\.0"),
        ('description = "test"', 'targets = "missing.bin"', r"targets: no such file"),
        ('description = "test"', "colour = 3", r"contains unknown field `colour`"),
        ("[[uav]]", "[uav]", r"uav: expected `array`, got `object`"),
        ("alt = 300.0", "alt = 1.0\n[[uav.extra]]", r"uav\[0\]: .* unknown field `extra`"),
    ],
)
def test_errors_name_the_file_and_the_field(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    assert old in VALID
    path = write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError, match=message) as caught:
        load_scenario(path)
    assert str(caught.value).startswith(str(path))


def test_repeated_piccolo_id_is_refused(tmp_path: Path) -> None:
    uav = VALID[VALID.index("[[uav]]") :]
    path = write(tmp_path, VALID + "\n" + uav)
    with pytest.raises(ScenarioError, match=r"uav\[1\]\.id: Piccolo ID 7 repeated"):
        load_scenario(path)


def test_aircraft_limits_are_configurable_and_checked(tmp_path: Path) -> None:
    text = VALID.replace("[wind]", "[aircraft]\nbank_limit = 45.0\nmax_airspeed = 35.0\n\n[wind]")
    scenario = load_scenario(write(tmp_path, text))
    assert scenario.limits.bank_limit_deg == 45.0
    assert scenario.limits.max_airspeed == 35.0
    bad = VALID.replace("[wind]", "[aircraft]\nbank_limit = 95.0\n\n[wind]")
    with pytest.raises(ScenarioError, match=r"aircraft: bank limit"):
        load_scenario(write(tmp_path, bad, "bad.toml"))


def test_unreadable_and_invalid_toml_name_the_file(tmp_path: Path) -> None:
    missing = tmp_path / "missing.toml"
    with pytest.raises(ScenarioError, match=r"missing\.toml: cannot read"):
        load_scenario(missing)
    broken = write(tmp_path, "[[uav]\nid = ", "broken.toml")
    with pytest.raises(ScenarioError, match=r"broken\.toml: not valid TOML"):
        load_scenario(broken)


def test_targets_file_is_resolved_beside_the_scenario(tmp_path: Path) -> None:
    source = shipped_scenario("head_on").targets_path
    assert source is not None
    (tmp_path / "t.bin").write_bytes(source.read_bytes())
    scenario = load_scenario(write(tmp_path, 'targets = "t.bin"\n' + VALID))
    assert scenario.targets() == shipped_scenario("head_on").targets()


def test_unknown_uav_id_lists_the_known_ones() -> None:
    with pytest.raises(ScenarioError, match=r"no uav with id 5 \(it has 74, 112\)"):
        shipped_scenario("head_on").uav(5)
