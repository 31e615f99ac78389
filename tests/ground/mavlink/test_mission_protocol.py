"""The mission upload protocol as a vehicle speaks it: each step, refusals by kind and
item, the retries and the cancel of a silent station, and the download items."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.messages import MAX_TARGETS, Target
from ground.mavlink.mission_protocol import (
    ITEM_RETRIES,
    ITEM_TIMEOUT_S,
    Complete,
    MissionItem,
    MissionUpload,
    Refuse,
    Request,
    download_item,
    item_from_message,
)

PARTNER = (255, 190)
WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT
GLOBAL = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def item(seq: int, lat: float = 35.7, lon: float = -120.8, **changes: int) -> MissionItem:
    return MissionItem(
        seq=seq,
        frame=changes.get("frame", GLOBAL),
        command=changes.get("command", WAYPOINT),
        lat=lat + seq * 0.01,
        lon=lon,
        alt=600.0,
        mission_type=changes.get("mission_type", mavlink2.MAV_MISSION_TYPE_MISSION),
    )


def start(count: int, now: float = 0.0) -> MissionUpload:
    upload, step = MissionUpload.start(PARTNER, count, mavlink2.MAV_MISSION_TYPE_MISSION, now)
    assert upload is not None
    assert step == Request(0)
    return upload


def test_an_upload_asks_for_each_item_then_completes_with_the_targets() -> None:
    upload = start(3)
    assert upload.on_item(item(0), 0.1) == Request(1)
    assert upload.on_item(item(1), 0.2) == Request(2)
    step = upload.on_item(item(2), 0.3)
    assert isinstance(step, Complete)
    assert step.targets == tuple(Target(35.7 + i * 0.01, -120.8, 600.0) for i in range(3))


@pytest.mark.parametrize(
    ("count", "mission_type", "result"),
    [
        (65535, mavlink2.MAV_MISSION_TYPE_MISSION, mavlink2.MAV_MISSION_NO_SPACE),
        (MAX_TARGETS + 1, mavlink2.MAV_MISSION_TYPE_MISSION, mavlink2.MAV_MISSION_NO_SPACE),
        (0, mavlink2.MAV_MISSION_TYPE_MISSION, mavlink2.MAV_MISSION_DENIED),
        (3, mavlink2.MAV_MISSION_TYPE_FENCE, mavlink2.MAV_MISSION_UNSUPPORTED),
        (3, mavlink2.MAV_MISSION_TYPE_RALLY, mavlink2.MAV_MISSION_UNSUPPORTED),
    ],
)
def test_a_count_the_fleet_cannot_take_is_refused_before_any_item(
    count: int, mission_type: int, result: int
) -> None:
    upload, step = MissionUpload.start(PARTNER, count, mission_type, 0.0)
    assert upload is None
    assert isinstance(step, Refuse)
    assert step.refusal.result == result


def test_the_largest_mission_is_taken() -> None:
    start(MAX_TARGETS)


@pytest.mark.parametrize(
    ("bad", "result", "named"),
    [
        (
            item(1, command=mavlink2.MAV_CMD_NAV_LOITER_UNLIM),
            mavlink2.MAV_MISSION_UNSUPPORTED,
            "MAV_CMD_NAV_LOITER_UNLIM",
        ),
        (
            item(1, command=mavlink2.MAV_CMD_NAV_TAKEOFF),
            mavlink2.MAV_MISSION_UNSUPPORTED,
            "MAV_CMD_NAV_TAKEOFF",
        ),
        (
            item(1, frame=mavlink2.MAV_FRAME_LOCAL_NED),
            mavlink2.MAV_MISSION_UNSUPPORTED_FRAME,
            "frame",
        ),
        (item(1, lat=95.0), mavlink2.MAV_MISSION_INVALID_PARAM5_X, "latitude"),
        (item(1, lon=math.nan), mavlink2.MAV_MISSION_INVALID_PARAM6_Y, "longitude"),
        (
            MissionItem(1, GLOBAL, WAYPOINT, 35.7, -120.8, math.inf),
            mavlink2.MAV_MISSION_INVALID_PARAM7,
            "altitude",
        ),
    ],
)
def test_an_item_the_fleet_cannot_fly_ends_the_upload_with_its_error_naming_it(
    bad: MissionItem, result: int, named: str
) -> None:
    upload = start(3)
    upload.on_item(item(0), 0.1)
    step = upload.on_item(bad, 0.2)
    assert isinstance(step, Refuse)
    assert step.refusal.result == result
    assert "mission item 1" in step.refusal.reason
    assert named in step.refusal.reason


def test_a_repeated_item_is_ignored_and_one_out_of_order_asks_again() -> None:
    upload = start(3)
    upload.on_item(item(0), 0.1)
    assert upload.on_item(item(0), 0.2) is None
    assert upload.on_item(item(2), 0.3) == Request(1)
    assert upload.on_item(item(1), 0.4) == Request(2)


def test_an_item_of_another_mission_type_is_ignored() -> None:
    upload = start(2)
    assert upload.on_item(item(0, mission_type=mavlink2.MAV_MISSION_TYPE_FENCE), 0.1) is None
    assert upload.expected == 0


def test_a_silent_station_is_asked_again_then_the_upload_is_cancelled() -> None:
    upload = start(2, now=0.0)
    assert upload.on_tick(ITEM_TIMEOUT_S / 2) is None
    now = 0.0
    for _ in range(ITEM_RETRIES):
        now += ITEM_TIMEOUT_S
        assert upload.on_tick(now) == Request(0)
    now += ITEM_TIMEOUT_S
    step = upload.on_tick(now)
    assert isinstance(step, Refuse)
    assert step.refusal.result == mavlink2.MAV_MISSION_OPERATION_CANCELLED
    assert "no mission item 0" in step.refusal.reason


def test_an_answer_resets_the_retries() -> None:
    upload = start(2, now=0.0)
    now = 0.0
    for _ in range(ITEM_RETRIES):
        now += ITEM_TIMEOUT_S
        upload.on_tick(now)
    assert upload.on_item(item(0), now) == Request(1)
    assert upload.on_tick(now + ITEM_TIMEOUT_S) == Request(1)


def test_items_from_either_message() -> None:
    as_int = mavlink2.MAVLink_mission_item_int_message(
        1, 1, 2, GLOBAL, WAYPOINT, 0, 1, 0, 0, 0, 0, 357000000, -1208000000, 600.0
    )
    as_float = mavlink2.MAVLink_mission_item_message(
        1, 1, 2, mavlink2.MAV_FRAME_GLOBAL, WAYPOINT, 0, 1, 0, 0, 0, 0, 35.7, -120.8, 600.0
    )
    for message in (as_int, as_float):
        got = item_from_message(message)
        assert (got.seq, got.command) == (2, WAYPOINT)
        assert got.lat == pytest.approx(35.7)
        assert got.lon == pytest.approx(-120.8)


def test_download_items_are_the_targets_with_the_current_one_marked() -> None:
    targets = (Target(35.7, -120.8, 600.0), Target(35.71, -120.79, 610.0))
    first = download_item(targets, 0, 1, PARTNER)
    second = download_item(targets, 1, 1, PARTNER)
    assert first is not None and second is not None
    assert (first.seq, first.current, first.command) == (0, 0, WAYPOINT)
    assert (second.seq, second.current) == (1, 1)
    assert (second.x, second.y, second.z) == (357100000, -1207900000, 610.0)
    assert (second.target_system, second.target_component) == PARTNER
    assert download_item(targets, 2, 1, PARTNER) is None
    assert download_item(targets, -1, 1, PARTNER) is None
