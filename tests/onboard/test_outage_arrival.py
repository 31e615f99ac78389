"""Reading an arrival hidden by a link outage from the fixes either side of it."""

from __future__ import annotations

from fleet.geo.mercator import MercatorProjection
from fleet.mission.messages import Target
from fleet.piccolo.telemetry import GpsBlock
from onboard.outage_arrival import FixHistory, passed_target

PLANE = MercatorProjection(35.72, -120.765)
TARGET = Target(*PLANE.to_latlon(0.0, 0.0), 600.0)


def fix(x: float, y: float, ms: int, east: float = 22.0, north: float = 0.0) -> GpsBlock:
    lat, lon = PLANE.to_latlon(x, y)
    return GpsBlock(lat, lon, 600.0, north, east, 0.0, gps_time_of_week_ms=ms)


def test_an_aircraft_that_held_its_course_through_the_target_passed_it() -> None:
    # 400 m before it, then 300 m beyond it 32 s later at 22 m/s: 700 m flown.
    assert passed_target(fix(-400, 0, 0), fix(300, 0, 32_000), TARGET, 75.0)


def test_an_aircraft_turned_away_far_from_the_target_did_not() -> None:
    # 1500 m short of it, then 1200 m short of it 20 s later, heading back: 440 m flown
    # at most, and the target's radius is 1425 m away.
    assert not passed_target(fix(-1500, 0, 0), fix(-1200, 200, 20_000, east=-22.0), TARGET, 75.0)


def test_fixes_out_of_order_say_nothing() -> None:
    assert not passed_target(fix(-100, 0, 5000), fix(100, 0, 5000), TARGET, 75.0)


def test_the_fix_before_the_outage_is_kept_once_fixes_flow_again() -> None:
    history = FixHistory()
    first, second, after = fix(-500, 0, 0), fix(-480, 0, 1000), fix(200, 0, 30_000)
    history.on_fix(first, 0)
    history.on_fix(second, 0)
    assert history.fresh_since(0) and history.before_outage is None
    assert not history.fresh_since(1)  # the outage was seen; no fix since
    history.on_fix(after, 1)
    assert history.before_outage == second and history.latest == after
    assert history.fresh_since(1)
