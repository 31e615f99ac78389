"""Which channel and schema each fleet key is recorded on."""

from __future__ import annotations

import json

import pytest

from fleet.recording import channels


@pytest.mark.parametrize(
    ("pattern", "key", "expected"),
    [
        ("uav/*/telemetry", "uav/7/telemetry", True),
        ("uav/*/telemetry", "uav/7/track", False),
        ("uav/*/cmd/**", "uav/7/cmd/waypoint", True),
        ("uav/*/cmd/**", "uav/7/cmd", True),
        ("fleet/**", "fleet/mission/3/targets", True),
        ("mission/*/targets", "mission/3/targets/extra", False),
    ],
)
def test_key_expression_matching(pattern: str, key: str, expected: bool) -> None:
    assert channels.matches(pattern, key) is expected


@pytest.mark.parametrize(
    ("key", "command"),
    [
        ("fleet/uav/7/opm", True),
        ("fleet/uav/7/cmd/track", True),
        ("fleet/mission/2/targets", True),
        ("replay/mission/2/abort", True),
        ("fleet/uav/7/telemetry", False),
        ("fleet/uav/7/state", False),
        ("fleet/mission/2/assignment/7", False),
        ("fleet/mission/2/result/7", False),
    ],
)
def test_commands_are_told_from_state(key: str, command: bool) -> None:
    assert channels.is_command(key) is command


def test_each_published_key_gets_its_generated_json_schema() -> None:
    spec = channels.channel_for("fleet/uav/112/telemetry")
    assert spec.topic == "fleet/uav/112/telemetry"
    assert spec.pattern == "fleet/uav/*/telemetry"
    assert spec.schema_name == "Telemetry"
    assert json.loads(spec.schema)["title"] == "Telemetry"
    assert channels.channel_for("fleet/uav/1/state").schema_name == "UavState"
    assert channels.channel_for("fleet/mission/4/assignment/1").schema_name == "AssignmentReport"
    assert channels.channel_for("fleet/uav/1/waypoint/90").schema_name == "Waypoint"


def test_unknown_keys_are_recorded_without_a_schema() -> None:
    spec = channels.channel_for("fleet/something/else")
    assert spec.schema_name == "" and spec.schema == b"" and spec.pattern == spec.topic


def test_location_fix_from_telemetry_for_foxglove_maps() -> None:
    telemetry = {"system_time_ms": 5, "gps": {"lat": 35.7, "lon": -120.7, "alt": 600.0}}
    fix = channels.location_fix(telemetry, 74, 3_500_000_001)
    assert fix is not None
    assert (fix["latitude"], fix["longitude"], fix["altitude"]) == (35.7, -120.7, 600.0)
    assert fix["timestamp"] == {"sec": 3, "nsec": 500_000_001}
    assert channels.location_fix({"system_time_ms": 5}, 74, 0) is None
    assert channels.location_fix({"gps": {"lat": "x"}}, 74, 0) is None
    spec = channels.location_channel("fleet", 74)
    assert spec.schema_name == "foxglove.LocationFix"
    assert json.loads(spec.schema)["title"] == "foxglove.LocationFix"


def test_moving_a_key_under_another_prefix() -> None:
    assert channels.with_prefix("fleet/uav/1/telemetry", "replay") == "replay/uav/1/telemetry"
