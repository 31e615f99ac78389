"""Whether the air moved away from the air this UAV's plan timed its legs in.

Each UAV's legs are timed in the airspeed and smoothed wind its digested result (or its
standing, for a re-plan solved again) carried (fleet.consensus.legs). The weather drifts
after the plan: a leg flown minutes later is flown in air the plan never saw. This
watch compares the air the module flies in now (`LinkWatch.smoothed_airspeed` and the
smoothed wind, both averaged over the wind's 20 s) with the air of the plan in force,
and says when the UAV should ask its team for a re-plan in the air of now (an epoch of
its own, fleet.consensus.membership `asked`), so gusts never make one:

* the air now is the module's smoothed air averaged again over `average_s` of the
  aircraft's clock: at real time the 20 s average still wanders ~0.4 m/s in the `windy`
  scenario's gusts (0.8 m/s, 5 s), and a re-plan is for the weather's drift;
* the change must exceed `change_mps` (the wind as a vector, or the airspeed), and stay
  above `clear_mps` (hysteresis) for `dwell_s` of the aircraft's clock: a gust that the
  averages let through for a few seconds is not a change of the weather;
* at most one ask per `interval_s` of the aircraft's clock, counted from this UAV's last
  ask and from when the plan in force changed the air it is timed in (any re-plan, the
  team's or its own: after one, every UAV's reference is its fresh standing's air).

Before a leg begins (the UAV within `BEFORE_LEG_S` of the target it flies, with more of
its queue after it) the watch asks on a smaller change (`before_leg_mps`, held
`before_leg_dwell_s`, `before_leg_interval_s` after the plan's air last changed). A
drift asks on the threshold only once it is large, minutes after it began; a leg timed
in the air of its start is what the plan promises, and the next leg is about to be
flown in the air of now. So the moment a leg begins is when a smaller change is worth a
re-plan, and it comes at most once a leg: gusts can make one there, never a run of them.

Times are the aircraft's clock (telemetry `system_time_ms`): mission time, whatever the
simulator's speedup. A clock that goes back (an autopilot restart) starts the waits
again from there. Pure: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from fleet.geo.wind import Wind
from onboard.time_average import TimeAverage

#: A wind (vector) or airspeed change this large (m/s) from the plan's makes a re-plan:
#: 0.7 m/s along an upwind leg at 22 m/s in a 10 m/s wind is ~6 % of its time.
AIR_CHANGE_MPS = 0.7
#: Below this change (m/s) the air counts as the plan's again (the hysteresis band).
AIR_CLEAR_MPS = 0.5
#: The air now is averaged over this long (s, aircraft clock) before it is compared.
AIR_AVERAGE_S = 60.0
#: The change must hold this long (s, aircraft clock) before the UAV asks.
AIR_DWELL_S = 30.0
#: At most one ask per this long (s, aircraft clock), and none this soon after the plan
#: in force changed its air.
AIR_INTERVAL_S = 150.0
#: A UAV this close (s of its ground speed) to the target it flies, with legs after it,
#: is about to begin a leg: the watch then asks on the smaller change below. Long enough
#: for a re-plan to be committed before the arrival (a standing waits up to 3 s wall).
BEFORE_LEG_S = 60.0
#: The change (m/s) that asks just before a leg: 0.5 m/s along an upwind leg at 22 m/s
#: in a 10 m/s wind is ~4 % of its time; the band below which it clears. Replayed in the
#: `windy` scenario's gusts alone (bench/bench_air_watch.py), 0.4 asked at a third of the
#: leg starts, 0.5 at one in seven, 0.6 at one in fifty but let legs begin ~5 % off.
BEFORE_LEG_MPS = 0.5
BEFORE_LEG_CLEAR_MPS = 0.35
#: How long (s, aircraft clock) the change must hold just before a leg, and how long
#: after the plan's air changed (or this UAV asked) it may ask there.
BEFORE_LEG_DWELL_S = 5.0
BEFORE_LEG_INTERVAL_S = 60.0


@dataclass(frozen=True, slots=True)
class FlyingAir:
    """An airspeed (m/s; None where the autopilot reports no air data: a GPS velocity
    less the wind moves with every turn, so it is not compared) and a wind: what a leg
    is timed in."""

    airspeed: float | None
    wind: Wind

    def off_by(self, other: FlyingAir) -> float:
        """The larger of the wind's vector change and the airspeed's change (m/s)."""
        wind = math.hypot(self.wind.east - other.wind.east, self.wind.north - other.wind.north)
        if self.airspeed is None or other.airspeed is None:
            return wind
        return max(wind, abs(self.airspeed - other.airspeed))


@dataclass
class AirWatch:
    change_mps: float = AIR_CHANGE_MPS
    clear_mps: float = AIR_CLEAR_MPS
    dwell_s: float = AIR_DWELL_S
    interval_s: float = AIR_INTERVAL_S
    average_s: float = AIR_AVERAGE_S
    before_leg_mps: float = BEFORE_LEG_MPS
    before_leg_clear_mps: float = BEFORE_LEG_CLEAR_MPS
    before_leg_dwell_s: float = BEFORE_LEG_DWELL_S
    before_leg_interval_s: float = BEFORE_LEG_INTERVAL_S
    #: The air the plan in force times this UAV's legs in; None: nothing to compare.
    reference: FlyingAir | None = None
    #: When (aircraft clock) the reference last changed, or this UAV last asked.
    _quiet_from: float | None = None
    #: Since when the change has been above the threshold (and not below the band).
    _over_since: float | None = None
    _last_clock: float | None = None
    #: The air now (its wind, and its airspeed where it has one), averaged over
    #: `average_s` of the aircraft's clock.
    _wind: TimeAverage = field(init=False, repr=False, compare=False)
    _airspeed: TimeAverage = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._wind = TimeAverage(self.average_s)
        self._airspeed = TimeAverage(self.average_s)

    def follow(self, air: FlyingAir | None, clock: float | None) -> None:
        """The plan in force times this UAV's legs in `air` (None: it does not say)."""
        if air == self.reference:
            return
        self.reference = air
        self._over_since = None
        if clock is not None:
            self._quiet_from = clock

    def check(
        self, now_air: FlyingAir | None, clock: float | None, before_leg: bool = False
    ) -> bool:
        """True when this UAV should ask for a re-plan in `now_air` (the air it flies in
        now, at `clock` on the aircraft's clock; `before_leg`: it is about to begin a leg
        the plan timed, `BEFORE_LEG_S`); the ask is counted then."""
        if clock is None or not math.isfinite(clock):
            return False
        last = self._last_clock
        if last is not None and clock < last:
            self._quiet_from = clock  # the autopilot's clock restarted: wait again
            self._over_since = None
        self._last_clock = clock
        if self._quiet_from is None:
            self._quiet_from = clock
        average = self._averaged(now_air, clock)
        reference = self.reference
        if reference is None or average is None:
            self._over_since = None
            return False
        change, clear, dwell, interval = (
            (
                self.before_leg_mps,
                self.before_leg_clear_mps,
                self.before_leg_dwell_s,
                self.before_leg_interval_s,
            )
            if before_leg
            else (self.change_mps, self.clear_mps, self.dwell_s, self.interval_s)
        )
        off = average.off_by(reference)
        if off < clear or (self._over_since is None and off <= change):
            self._over_since = None
            return False
        if self._over_since is None:
            self._over_since = clock
        if clock - self._over_since < dwell or clock - self._quiet_from < interval:
            return False
        self._quiet_from = clock
        self._over_since = None
        return True

    def _averaged(self, air: FlyingAir | None, clock: float) -> FlyingAir | None:
        """`air` averaged in at `clock` (onboard.time_average: the first reading, or one
        after a gap in the readings or a clock gone back, as it is)."""
        if air is None:
            self._wind.reset()
            self._airspeed.reset()
            return None
        east, north = self._wind.add((air.wind.east, air.wind.north), clock)
        speed = air.airspeed
        if speed is None:
            self._airspeed.reset()
        else:
            (speed,) = self._airspeed.add((speed,), clock)
        return FlyingAir(speed, Wind(east, north))
