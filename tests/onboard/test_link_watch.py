"""Watching the autopilot link (onboard.link_watch)."""

from __future__ import annotations

import math

import msgspec
import pytest

from fleet.geo.wind import airspeed
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MissionTargets,
    UavResult,
)
from fleet.mission.phase import Phase
from onboard.core import (
    LINK_LOST_S,
)
from onboard.link_watch import LinkWatch
from tests.onboard.core_harness import (
    TARGETS,
    make_core,
)
from tests.support.link_samples import sample_telemetry

SPACE = KeySpace()


def test_lost_telemetry_is_link_lost_and_declines_a_mission() -> None:
    core, out = make_core()  # telemetry at t=0
    core.tick(LINK_LOST_S + 1.0)
    state = core.state(LINK_LOST_S + 1.0)
    assert state.phase == Phase.LINK_LOST and state.reason is not None
    assert any(s.startswith("error: autopilot link lost") for s in out.statuses())
    core.on_targets(MissionTargets(mission=1, team=(112,), targets=TARGETS), LINK_LOST_S + 2)
    assert out.on(SPACE.mission_result(1, 112)) == [UavResult(1, 112, (None, None, None))]
    assert out.autopilot == []
    core.on_telemetry(sample_telemetry(), LINK_LOST_S + 3)
    assert core.state(LINK_LOST_S + 3).phase != Phase.LINK_LOST


def test_the_watch_says_lost_once_and_back_once() -> None:
    said: list[str] = []
    watch = LinkWatch(lambda kind, text, now, **_: said.append(text))
    assert watch.lost(0.0)  # no telemetry ever came
    watch.check(10.0)
    assert said == []  # nothing flowed yet, so nothing stopped
    watch.on_telemetry(sample_telemetry(), 1.0)
    assert not watch.lost(1.0 + LINK_LOST_S) and watch.lost(1.1 + LINK_LOST_S)
    watch.check(2.0 + LINK_LOST_S)
    watch.check(3.0 + LINK_LOST_S)
    watch.on_telemetry(sample_telemetry(), 4.0 + LINK_LOST_S)
    assert [s.split(":")[0] for s in said] == ["error", "autopilot link back"]


def test_the_airspeed_held_is_the_air_datas_else_the_gps_less_the_smoothed_wind() -> None:
    watch = LinkWatch(lambda *_args, **_kwargs: None)
    assert watch.airspeed() is None  # no telemetry, no GPS fix
    telemetry = sample_telemetry()
    assert telemetry.gps is not None and telemetry.sensor is not None
    sensor = telemetry.sensor
    thin_air = msgspec.structs.replace(sensor, indicated_airspeed=20.0, density_ratio=0.64)
    watch.on_telemetry(msgspec.structs.replace(telemetry, sensor=thin_air), 0.0)
    assert watch.airspeed() == pytest.approx(25.0)  # 20 / sqrt(0.64)
    # No usable air data: the GPS velocity less the smoothed wind (fleet.geo.wind.airspeed).
    no_pitot = msgspec.structs.replace(telemetry.sensor, indicated_airspeed=0.0, wind_west=-4.0)
    watch.on_telemetry(msgspec.structs.replace(telemetry, sensor=no_pitot), 1.0)
    gps = telemetry.gps
    expected = airspeed((gps.vel_east, gps.vel_north), watch.wind.value)
    assert watch.wind.value.east > 0.0 and watch.airspeed() == pytest.approx(expected)


def test_the_smoothed_airspeed_averages_the_air_data_over_the_wind_s_time_constant() -> None:
    """A gust's reading moves it by the share of the time constant that passed; with no
    air data ever, it is the airspeed held."""
    watch = LinkWatch(lambda *_args, **_kwargs: None)
    telemetry = sample_telemetry()
    base = telemetry.sensor
    assert base is not None and telemetry.gps is not None
    assert watch.smoothed_airspeed() is None

    def reading(speed: float, now: float) -> None:
        sensor = msgspec.structs.replace(base, indicated_airspeed=speed, density_ratio=1.0)
        watch.on_telemetry(msgspec.structs.replace(telemetry, sensor=sensor), now)

    reading(22.0, 0.0)
    assert watch.smoothed_airspeed() == pytest.approx(22.0)  # the first, as it is
    reading(25.0, 1.0)  # a gust: the instant's reading, not the mean
    assert watch.airspeed() == pytest.approx(25.0)
    weight = 1.0 - math.exp(-1.0 / watch.wind.time_constant_s)
    assert watch.smoothed_airspeed() == pytest.approx(22.0 + 3.0 * weight)
    reading(22.0, 0.5)  # a wall clock gone back, the aircraft's standing: no time passed
    assert watch.smoothed_airspeed() == pytest.approx(22.0 + 3.0 * weight)
    plain = LinkWatch(lambda *_args, **_kwargs: None)
    no_pitot = msgspec.structs.replace(base, indicated_airspeed=0.0)
    plain.on_telemetry(msgspec.structs.replace(telemetry, sensor=no_pitot), 0.0)
    assert plain.smoothed_airspeed() == pytest.approx(plain.airspeed())


def test_the_averages_run_on_the_aircraft_s_clock_whatever_the_speedup() -> None:
    """A simulator at speedup 4 flies 4 s of weather a wall second: the wind and the
    airspeed are averaged over the aircraft's seconds (telemetry `system_time_ms`), so
    their time constant spans the same weather at any speedup."""
    watch = LinkWatch(lambda *_args, **_kwargs: None)
    base = sample_telemetry().sensor
    assert base is not None

    def reading(speed: float, wind_west: float, time_ms: int, wall: float) -> None:
        sensor = msgspec.structs.replace(
            base, indicated_airspeed=speed, density_ratio=1.0, wind_south=0.0, wind_west=wind_west
        )
        watch.on_telemetry(msgspec.structs.replace(sample_telemetry(time_ms), sensor=sensor), wall)

    reading(22.0, -10.0, 1000, 0.0)
    reading(25.0, -12.0, 5000, 1.0)  # 4 s of the aircraft's time in 1 s of the wall's
    weight = 1.0 - math.exp(-4.0 / watch.wind.time_constant_s)
    assert watch.clock.now_s == pytest.approx(4.0)
    assert watch.air_data_airspeed() == pytest.approx(22.0 + 3.0 * weight)
    assert watch.wind.value.east == pytest.approx(10.0 + 2.0 * weight)
