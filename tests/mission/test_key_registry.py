"""The key registry: every key declared once, built and parsed by a KeySpace."""

from __future__ import annotations

import inspect

import msgspec
import pytest

from fleet.mission import key_registry as reg
from fleet.mission import messages
from fleet.mission.key_registry import REGISTRY, KeySpec
from fleet.mission.key_space import KeySpace, checked_prefix, space_of

SAMPLE_IDS = {reg.UAV_ID: 74, reg.MISSION_ID: 5, reg.INDEX: 3}
#: Structs of messages.py that only travel inside another (or decode part of one).
NESTED = {
    messages.Target,
    messages.MissionProgress,
    messages.AssignmentHeader,
    messages.NoFlyZone,
}


def _name(spec: KeySpec) -> str:
    return spec.pattern


@pytest.mark.parametrize("spec", REGISTRY, ids=_name)
@pytest.mark.parametrize("prefix", ["fleet", "replay"])
def test_every_key_round_trips_pattern_to_key_to_parse(spec: KeySpec, prefix: str) -> None:
    space = KeySpace(prefix)
    ids = {name: SAMPLE_IDS[name] for name in spec.placeholders}
    key = space.key(spec, **ids)
    assert "{" not in key and "*" not in key
    parsed = space.parse(key)
    assert parsed is not None and parsed.spec is spec
    found = {reg.UAV_ID: parsed.uav, reg.MISSION_ID: parsed.mission, reg.INDEX: parsed.index}
    assert found == {name: str(ids[name]) if name in ids else None for name in found}
    assert KeySpace("other").parse(key) is None


def test_patterns_are_distinct_and_use_known_placeholders() -> None:
    assert len({spec.pattern for spec in REGISTRY}) == len(REGISTRY)
    for spec in REGISTRY:
        assert set(spec.placeholders) <= set(reg.PLACEHOLDERS), spec.pattern
        assert spec.tree in ("uav", "mission", "router", "roster")


def test_every_message_that_travels_on_a_key_is_in_the_registry() -> None:
    structs = {
        value
        for value in vars(messages).values()
        if inspect.isclass(value)
        and issubclass(value, msgspec.Struct)
        and value.__module__ == messages.__name__
    }
    carried = {spec.message for spec in REGISTRY} | {spec.reply for spec in REGISTRY}
    assert structs - NESTED <= carried
    # and each carried struct has its JSON Schema file
    assert carried - {None} == set(reg.SCHEMA_FILES)


def test_a_keyspace_builds_the_keys_and_wildcards_the_compatibility_layer_does() -> None:
    space = KeySpace("lab")
    assert space.telemetry(7) == "lab/uav/7/telemetry"
    assert space.waypoint(7, 2) == "lab/uav/7/waypoint/2"
    assert space.command(7, "track") == "lab/uav/7/cmd/track"
    assert space.mission_assignment(3, 7) == "lab/mission/3/assignment/7"
    assert space.mission_results(3) == "lab/mission/3/result/*"
    assert space.all_alive == "lab/uav/*/alive"
    assert space.all_waypoints == "lab/uav/*/waypoint/*"
    assert space.all_mission_replans == "lab/mission/*/replan/*"
    assert space.all_mission_keys == "lab/mission/**"
    assert space.everything == "lab/**"
    assert space.uav_tree(7) == "lab/uav/7/**"
    replay = KeySpace("replay")
    assert replay.all_mission_assignments == "replay/mission/*/assignment/*"
    assert replay.mission_targets(3) == "replay/mission/3/targets"


@pytest.mark.parametrize("bad", ["", "a/b", "x*", "**"])
def test_a_keyspace_refuses_a_prefix_that_is_not_one_chunk(bad: str) -> None:
    with pytest.raises(ValueError, match="one key chunk"):
        checked_prefix(bad)
    with pytest.raises(ValueError, match="one key chunk"):
        KeySpace(bad)


def test_a_key_is_in_the_space_its_first_chunk_names() -> None:
    assert space_of("replay/uav/7/telemetry") == KeySpace("replay")
    assert space_of("lab/anything") is space_of("lab/else")  # one per prefix, kept
    assert space_of("re.play/uav/7/telemetry") is None
    assert space_of("/uav/7/telemetry") is None


def test_unregistered_keys_parse_to_nothing() -> None:
    space = KeySpace()
    for key in ("fleet/uav/7/other", "fleet/mission/5/result", "fleet/uav/7", "fleet"):
        assert space.parse(key) is None
