"""Whether the air moved away from the plan's (onboard.air_watch): a change of the
weather beyond the threshold, held, asks once; gusts never do."""

from __future__ import annotations

import math

from fleet.geo.wind import Wind
from onboard.air_watch import (
    AIR_CHANGE_MPS,
    AIR_DWELL_S,
    AIR_INTERVAL_S,
    BEFORE_LEG_DWELL_S,
    BEFORE_LEG_INTERVAL_S,
    BEFORE_LEG_MPS,
    AirWatch,
    FlyingAir,
)

PLAN = FlyingAir(22.0, Wind(10.0, 0.0))


def _watch() -> AirWatch:
    """The watch with no averaging of its own: the air given is the air compared."""
    return AirWatch(average_s=0.0)


def _asks(watch: AirWatch, air_at: list[tuple[float, FlyingAir]]) -> list[float]:
    return [clock for clock, air in air_at if watch.check(air, clock)]


def test_a_change_beyond_the_threshold_held_for_the_dwell_asks_once_after_the_interval() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    moved = FlyingAir(22.0, Wind(10.0, 1.2))  # the wind turned: 1.2 m/s off as a vector
    asks = _asks(watch, [(float(t), moved) for t in range(0, 400)])
    # Over from the start, but the plan is younger than the interval until then; with
    # no re-plan to change the reference, it asks again one interval later, not before.
    assert asks == [AIR_INTERVAL_S, 2 * AIR_INTERVAL_S]


def test_the_dwell_counts_from_when_the_change_crossed_the_threshold() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    air = [(float(t), PLAN) for t in range(0, 300)]
    air += [(float(t), FlyingAir(22.0, Wind(11.1, 0.0))) for t in range(300, 400)]
    assert _asks(watch, air) == [300.0 + AIR_DWELL_S]


def test_a_new_reference_restarts_the_interval_and_clears_the_change() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    moved = FlyingAir(22.0, Wind(11.5, 0.0))  # 1.5 m/s off
    assert _asks(watch, [(float(t), moved) for t in range(0, 100)]) == []
    watch.follow(moved, 100.0)  # the team re-planned in the air of now
    assert _asks(watch, [(float(t), moved) for t in range(100, 1000)]) == []


def test_gusts_below_the_threshold_or_shorter_than_the_dwell_never_ask() -> None:
    air = []
    for t in range(0, 3000):
        # The smoothed wind wanders 0.45 m/s about the plan's (inside the band), and
        # every 60 s a strong gust lifts it 1.6 m/s off for 15 s (shorter than the dwell).
        off = 1.6 if t % 60 < 15 else 0.45 * math.sin(t / 7.0)
        air.append((float(t), FlyingAir(22.0, Wind(10.0 + off, 0.0))))
    watch = _watch()
    watch.follow(PLAN, 0.0)
    assert _asks(watch, air) == []
    # Averaged over a minute (the default), a wander of 0.9 m/s and strong short gusts
    # every minute stay under the threshold too.
    air = []
    for t in range(0, 3000):
        off = 2.0 if t % 60 < 8 else 0.9 * math.sin(t / 7.0)
        air.append((float(t), FlyingAir(22.0, Wind(10.0 + off, 0.0))))
    watch = AirWatch()
    watch.follow(PLAN, 0.0)
    assert _asks(watch, air) == []


def test_the_air_now_is_averaged_before_it_is_compared() -> None:
    watch = AirWatch()
    watch.follow(PLAN, 0.0)
    moved = FlyingAir(22.0, Wind(11.2, 0.0))
    air = [(float(t), PLAN if t < 200 else moved) for t in range(0, 330)]
    asks = _asks(watch, air)
    # The average crosses 0.7 m/s of the 1.2 m/s step ~52 s after it, then the dwell.
    crossed = 200.0 + 60.0 * math.log(1.2 / (1.2 - AIR_CHANGE_MPS))
    assert len(asks) == 1 and abs(asks[0] - (crossed + AIR_DWELL_S)) <= 1.5


def test_the_hysteresis_band_keeps_a_change_that_dips_below_the_threshold() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    air = []
    for t in range(200, 260):
        off = 0.8 if t % 10 < 5 else 0.6  # dips below the threshold, never below the band
        air.append((float(t), FlyingAir(22.0, Wind(10.0 + off, 0.0))))
    assert _asks(watch, air) == [200.0 + AIR_DWELL_S]


def test_the_airspeed_counts_where_both_say_one_and_not_where_one_does_not() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    slower = FlyingAir(22.0 - AIR_CHANGE_MPS - 0.2, PLAN.wind)
    assert _asks(watch, [(float(t), slower) for t in range(0, 200)]) == [AIR_INTERVAL_S]
    watch = _watch()
    watch.follow(FlyingAir(None, PLAN.wind), 0.0)  # no air data: the wind alone
    assert _asks(watch, [(float(t), slower) for t in range(0, 400)]) == []


def test_no_reference_or_a_clock_that_goes_back_asks_nothing() -> None:
    watch = _watch()
    moved = FlyingAir(22.0, Wind(12.0, 0.0))
    assert _asks(watch, [(float(t), moved) for t in range(0, 400)]) == []  # no plan's air
    watch.follow(PLAN, 400.0)
    assert _asks(watch, [(float(t), moved) for t in range(400, 500)]) == []
    # The autopilot restarted: its clock from 0 again; the interval starts there.
    assert _asks(watch, [(float(t), moved) for t in range(0, 200)]) == [AIR_INTERVAL_S]


def test_just_before_a_leg_a_smaller_change_asks_once_the_leg_s_interval_passed() -> None:
    """0.5 m/s off never asks in flight (under the threshold), but about to begin a leg
    it does, after its short dwell, once `BEFORE_LEG_INTERVAL_S` passed since the plan's
    air changed; then not again until the plan's air changes or the interval passes."""
    watch = _watch()
    watch.follow(PLAN, 0.0)
    drifted = FlyingAir(22.0, Wind(10.0, BEFORE_LEG_MPS + 0.1))
    assert _asks(watch, [(float(t), drifted) for t in range(0, 400)]) == []
    asks = [t for t in range(400, 460) if watch.check(drifted, float(t), before_leg=True)]
    assert asks == [400 + BEFORE_LEG_DWELL_S]
    watch.follow(drifted, 410.0)  # the team re-planned in the air of now
    assert [t for t in range(410, 600) if watch.check(drifted, float(t), True)] == []
    soon = _watch()
    soon.follow(PLAN, 0.0)  # a plan younger than the interval: it waits for it
    asks = [t for t in range(0, 100) if soon.check(drifted, float(t), before_leg=True)]
    assert asks == [BEFORE_LEG_INTERVAL_S]


def test_just_before_a_leg_air_within_the_smaller_change_asks_nothing() -> None:
    watch = _watch()
    watch.follow(PLAN, 0.0)
    near = FlyingAir(22.0, Wind(10.0 + BEFORE_LEG_MPS - 0.05, 0.0))
    assert [t for t in range(0, 600) if watch.check(near, float(t), before_leg=True)] == []
