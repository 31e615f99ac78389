"""The simulator's incursion log (fleet.sim.zone_log): from its own positions."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from fleet.mission.messages import NoFlyZone
from fleet.sim.autopilot import AutopilotSettings, SimulatedAutopilot
from fleet.sim.scenario import ScenarioError, load_scenario, shipped_scenario

SINGLE = shipped_scenario("single_uav")
UAV = SINGLE.uavs[0]
#: 600 m ahead of 112 (flying east from (35.72, -120.787104)), 400 m deep.
AHEAD = NoFlyZone(
    ring=((35.715, -120.7805), (35.715, -120.776), (35.725, -120.776), (35.725, -120.7805)),
    name="ahead",
)


def test_flying_through_a_zone_is_one_incursion_logged_as_an_error(
    caplog: pytest.LogCaptureFixture,
) -> None:
    autopilot = SimulatedAutopilot(UAV, AutopilotSettings(zones=(AHEAD,)))
    with caplog.at_level(logging.WARNING, logger="fleet.sim.zone_log"):
        autopilot.advance_to(60_000)
    assert autopilot.zone_log.incursions == 1
    entered = [r for r in caplog.records if r.levelno == logging.ERROR]
    assert len(entered) == 1 and "UAV 112 entered no-fly zone 0 (ahead)" in entered[0].message
    assert any("left no-fly zone 0 (ahead) after" in r.message for r in caplog.records)


def test_no_zones_no_incursion() -> None:
    autopilot = SimulatedAutopilot(UAV, AutopilotSettings())
    autopilot.advance_to(60_000)
    assert autopilot.zone_log.incursions == 0


def test_a_scenario_names_its_zones_file(tmp_path: Path) -> None:
    zones = tmp_path / "zones.geojson"
    ring = [[lon, lat] for lat, lon in AHEAD.ring]
    zones.write_text('{"type": "Polygon", "coordinates": [' + str([*ring, ring[0]]) + "]}")
    source = (
        Path(str(SINGLE.source))
        .read_text()
        .replace('targets = "single_uav_targets.bin"', 'no_fly = "zones.geojson"')
    )
    scenario_file = tmp_path / "s.toml"
    scenario_file.write_text(source)
    assert load_scenario(scenario_file).zones[0].ring[0] == AHEAD.ring[0]
    zones.write_text('{"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 0]]]}')
    with pytest.raises(ScenarioError, match=r"no_fly: .*not closed"):
        load_scenario(scenario_file)
