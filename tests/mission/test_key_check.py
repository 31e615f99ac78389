"""A message is believed only as far as its key vouches for it."""

from __future__ import annotations

import pytest

from fleet.mission import key_check
from fleet.mission.key_check import WrongKey, check_key, parse_key, uav_of
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentHeader,
    AssignmentReport,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    Target,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.piccolo.waypoint import Waypoint

SPACE = KeySpace()

TARGETS = (Target(35.7, -120.7, 600.0),)


def report(uav: int, mission: int = 5, **changes: object) -> AssignmentReport:
    fields: dict[str, object] = {
        "mission": mission, "uav": uav, "target": 0, "pairs": {uav: 0},
        "unassigned": (), "team": (uav,), "digest": "d",
    }  # fmt: skip
    fields.update(changes)
    return AssignmentReport(**fields)  # type: ignore[arg-type]


def state(uav: int, mission: MissionProgress | None = None) -> UavState:
    return UavState(uav, True, 1.0, None, None, None, mission)


@pytest.mark.parametrize(
    ("key", "message"),
    [
        (SPACE.mission_result(5, 74), UavResult(5, 74, (1.0,))),
        (SPACE.mission_assignment(5, 74), report(74)),
        (SPACE.mission_targets(5), MissionTargets(5, (74, 112), TARGETS)),
        (SPACE.mission_abort(0xFFFF_FFFF), MissionAbort(0xFFFF_FFFF)),
        (SPACE.state(74), state(74, MissionProgress(5, Phase.COMMITTED, 1, None, report(74)))),
        (SPACE.waypoint(74, 3), Waypoint(3, 4, 35.7, -120.7, 600.0)),
    ],
)
def test_a_message_on_its_own_key_passes(key: str, message: object) -> None:
    check_key(key, message)


@pytest.mark.parametrize(
    ("key", "message", "why"),
    [
        (SPACE.mission_result(5, 74), UavResult(5, 112, (1.0,)), "UAV 112, not the key's 74"),
        (SPACE.mission_assignment(5, 74), report(112), "UAV 112, not the key's 74"),
        (SPACE.mission_result(6, 74), UavResult(5, 74, (1.0,)), "mission 5, not the key's 6"),
        (SPACE.mission_abort(6), MissionAbort(7), "mission 7"),
        (SPACE.mission_targets(5), MissionTargets(5, (74, 0), TARGETS), "member 0"),
        (SPACE.mission_targets(2**32), MissionTargets(2**32, (74,), TARGETS), "outside"),
        (SPACE.mission_assignment(5, 74), report(74, target=70000), "target index"),
        (SPACE.mission_assignment(5, 74), report(74, pairs={0: 0}), "member 0"),
        (SPACE.state(999), state(74), "UAV 74, not the key's 999"),
        (SPACE.state(74), state(74, MissionProgress(2**40, Phase.IDLE, 0)), "not a u32"),
        (
            SPACE.state(74),
            state(74, MissionProgress(5, Phase.WAITING, 1, UavResult(5, 112, ()))),
            "112",
        ),
        (SPACE.waypoint(74, 3), Waypoint(4, 5, 35.7, -120.7, 600.0), "index 4"),
        ("fleet/uav/abc/state", state(74), "'abc' is not a decimal"),
        ("fleet/uav/+74/state", state(74), "not a decimal"),
        ("fleet/uav/70000/state", state(70000), "outside 1-65520"),
        ("o.ther/uav/74/state", state(74), "not a fleet message key"),  # not a prefix
    ],
)
def test_a_message_its_key_does_not_vouch_for_is_refused(
    key: str, message: object, why: str
) -> None:
    with pytest.raises(WrongKey, match=why):
        check_key(key, message)


def test_uav_of_and_parse_key() -> None:
    assert uav_of(SPACE.alive(299)) == 299
    assert uav_of(SPACE.mission_result(5, 74)) == 74
    assert parse_key(SPACE.mission_targets(9)).mission == 9
    with pytest.raises(WrongKey, match="names no UAV"):
        uav_of(SPACE.mission_targets(9))


def test_an_assignment_header_is_checked_against_its_key() -> None:
    check_key(SPACE.mission_assignment(5, 74), AssignmentHeader(5, 74, 1, (112,)))
    for key, header, why in [
        (SPACE.mission_assignment(5, 74), AssignmentHeader(5, 112), "UAV 112"),
        (SPACE.mission_assignment(6, 74), AssignmentHeader(5, 74), "mission 5"),
        (SPACE.mission_assignment(5, 74), AssignmentHeader(5, 74, 1, (0,)), "member 0"),
    ]:
        with pytest.raises(WrongKey, match=why):
            check_key(key, header)


def test_parsed_keys_are_remembered_within_a_bound() -> None:
    assert key_check.PARSED_KEYS <= 1024
    for mission in range(3 * key_check.PARSED_KEYS):
        assert parse_key(SPACE.mission_result(mission, 74)).mission == mission
    assert len(key_check._PICCOLO_IDS) <= key_check.PARSED_KEYS
    with pytest.raises(WrongKey):  # a refused key stays refused, each time
        parse_key("fleet/uav/0/state")
    with pytest.raises(WrongKey):
        parse_key("fleet/uav/0/state")
    # Under another prefix a key remembered under its own is not the fleet's.
    parse_key(SPACE.mission_result(5, 74))
    with pytest.raises(WrongKey, match="not a fleet message key"):
        parse_key(SPACE.mission_result(5, 74), KeySpace("replay"))


def test_a_key_is_parsed_under_its_own_prefix() -> None:
    replay = KeySpace("replay").mission_result(5, 74)
    assert parse_key(replay) == parse_key(SPACE.mission_result(5, 74))
    for key in ("re play/uav/74/state", "/uav/74/state", "fl.eet/mission/5/result/74"):
        with pytest.raises(WrongKey, match="not a fleet message key"):
            parse_key(key)
