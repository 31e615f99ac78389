"""The wind the approach model plans with: the autopilot's estimate, smoothed.

A Piccolo reports its wind estimate in every telemetry packet (`wind_south`,
`wind_west`). That estimate moves with every gust and with the estimator's own noise,
while an approach time is a promise over minutes: the mean wind matters, not the gust
of the moment. So the estimates are averaged over `time_constant_s` (an exponential
moving average in time, onboard.time_average: the main loop sees telemetry at an
irregular rate). The first estimate is taken as it is, so a module that starts
mid-flight plans with the wind at once. Pure: time comes in as `now` (the module's
link watch gives the aircraft's clock, so the average spans the weather's seconds
whatever a simulator's speedup).

An estimate that is not a number, or faster than `MAX_PLAUSIBLE_WIND` (no aircraft of
this fleet flies in it: a corrupt field), is dropped and counted, never averaged in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from fleet.geo.wind import CALM_AIR, Wind
from fleet.piccolo.telemetry import Telemetry
from onboard.time_average import TimeAverage

__all__ = ["DEFAULT_TIME_CONSTANT_S", "MAX_PLAUSIBLE_WIND", "WindEstimate"]

#: Seconds over which the autopilot's estimates are averaged: long enough to smooth
#: gusts (seconds) and short enough to follow the weather's drift (many minutes).
DEFAULT_TIME_CONSTANT_S = 20.0
#: m/s; a reported wind above this is dropped as corrupt.
MAX_PLAUSIBLE_WIND = 60.0


@dataclass
class WindEstimate:
    """The smoothed wind; feed it every telemetry the module sees."""

    time_constant_s: float = DEFAULT_TIME_CONSTANT_S
    value: Wind = CALM_AIR  #: the wind to plan with (calm until an estimate came)
    samples: int = 0  #: estimates averaged in
    dropped: int = 0  #: estimates refused (not a number, or implausibly fast)
    _average: TimeAverage = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._average = TimeAverage(self.time_constant_s)

    def on_telemetry(self, telemetry: Telemetry, now: float) -> None:
        if telemetry.sensor is not None:
            sensor = telemetry.sensor
            self.update(Wind.from_piccolo(sensor.wind_south, sensor.wind_west), now)

    def update(self, wind: Wind, now: float) -> None:
        if not (
            math.isfinite(wind.east)
            and math.isfinite(wind.north)
            and wind.speed <= MAX_PLAUSIBLE_WIND
        ):
            self.dropped += 1
            return
        self.samples += 1
        east, north = self._average.add((wind.east, wind.north), now)
        self.value = Wind(east, north)
