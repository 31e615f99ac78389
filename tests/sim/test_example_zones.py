"""The example no-fly zones shipped with the scenarios: read as the ground reads them,
clear of every target of their scenario, in the package."""

from __future__ import annotations

from importlib.resources import files

from fleet.files.targets_io import read_targets
from fleet.files.zones_file import read_zones
from fleet.mission.no_fly import mission_zone_problem


def test_head_on_zones_are_a_valid_zone_clear_of_its_targets() -> None:
    scenarios = files("fleet") / "scenarios"
    zones = read_zones(str(scenarios / "head_on_zones.geojson"))
    targets = read_targets(str(scenarios / "head_on_targets.bin"))
    assert [zone.name for zone in zones] == ["range hut"]
    assert mission_zone_problem(zones, targets) is None
