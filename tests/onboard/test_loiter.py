"""Loiters clear of no-fly zones (onboard.loiter): the leg and its turns keep the
clearance from every zone; a point too near a zone moves off it."""

from __future__ import annotations

import math

from fleet.geo.visibility import ZoneMap
from fleet.geo.zones import segment_enters
from onboard.loiter import LOITER_LENGTH_M, loiter_clearance, plan_loiter

SPEED = 22.0
BOX = ((0.0, 0.0), (400.0, 0.0), (400.0, 400.0), (0.0, 400.0))


def assert_clear(anchor: tuple[float, float], far: tuple[float, float]) -> None:
    clear_of = ZoneMap([BOX], loiter_clearance(SPEED))
    assert not clear_of.containing(anchor) and not clear_of.containing(far)
    assert not segment_enters(anchor, far, clear_of.zones[0])
    assert math.dist(anchor, far) == LOITER_LENGTH_M or math.isclose(
        math.dist(anchor, far), LOITER_LENGTH_M
    )


def test_a_clear_point_loiters_where_it_is_along_its_heading() -> None:
    found = plan_loiter((-1000.0, 200.0), math.pi, [BOX], SPEED)
    assert found is not None
    anchor, far = found
    assert anchor == (-1000.0, 200.0)
    assert far[0] < anchor[0] and math.isclose(far[1], 200.0, abs_tol=1e-6)  # west, ahead
    assert_clear(anchor, far)


def test_a_leg_heading_into_a_zone_turns_aside() -> None:
    found = plan_loiter((-400.0, 200.0), 0.0, [BOX], SPEED)  # heading east, at the box
    assert found is not None
    assert found[0] == (-400.0, 200.0)
    assert_clear(*found)


def test_a_point_too_near_a_zone_moves_off_it() -> None:
    start = (450.0, 200.0)  # 50 m east of the box: within the clearance
    assert ZoneMap([BOX], loiter_clearance(SPEED)).containing(start)
    found = plan_loiter(start, math.pi / 2, [BOX], SPEED)
    assert found is not None
    anchor, far = found
    assert anchor != start
    assert_clear(anchor, far)
    assert not segment_enters(start, anchor, BOX)  # the way there keeps out of it too


def test_walled_in_no_loiter() -> None:
    huge = ((-5000.0, -5000.0), (5000.0, -5000.0), (5000.0, 5000.0), (-5000.0, 5000.0))
    assert plan_loiter((0.0, 0.0), 0.0, [huge], SPEED) is None
