"""Watching the autopilot link: the latest telemetry, the wind and airspeed it reports
(smoothed on the aircraft's clock), and whether it stopped coming.

Telemetry silent for LINK_LOST_S counts as a lost link, said once when it happens and
once when telemetry flows again; what a lost link does to a held target is the target
flight's (onboard.target_flight).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from fleet.geo.wind import airspeed
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from onboard.planner.wind_estimate import WindEstimate
from onboard.state_report import Say
from onboard.time_average import AircraftClock, TimeAverage

#: With no telemetry for this long (wall seconds), the autopilot link counts as lost.
LINK_LOST_S = 3.0


@dataclass
class LinkWatch:
    say: Say
    telemetry: Telemetry | None = None
    telemetry_at: float | None = None  #: when the latest telemetry arrived
    #: How many times telemetry that was flowing stopped: what happened meanwhile
    #: (an arrival, say) was not seen by telemetry.
    outages: int = 0
    #: When the module started (None: not said; no telemetry yet then counts as lost).
    started_at: float | None = None
    _said_lost: bool = False
    wind: WindEstimate = field(default_factory=WindEstimate)
    #: The clock the averages run on: the weather's seconds, whatever the speedup.
    clock: AircraftClock = field(default_factory=AircraftClock)
    #: The air data's true airspeed averaged like the wind (`smoothed_airspeed`).
    _airspeed: TimeAverage | None = None

    def on_telemetry(self, telemetry: Telemetry, now: float) -> None:
        self.telemetry = telemetry
        self.telemetry_at = now
        aircraft_s = self.clock.tick(telemetry.system_time_ms, now)
        self.wind.on_telemetry(telemetry, aircraft_s)
        self._average_airspeed(telemetry, aircraft_s)
        if self._said_lost:
            self._said_lost = False
            self.say(StatusKind.LINK_BACK, "autopilot link back: telemetry flowing again", now)

    @property
    def gps(self) -> GpsBlock | None:
        return self.telemetry.gps if self.telemetry else None

    def airspeed(self) -> float | None:
        """The airspeed held (m/s): the air data's true airspeed where the autopilot
        reports one, else the GPS velocity less the smoothed wind; None without a GPS
        fix. The one airspeed the module plans, times, routes and flies with."""
        sensor = self.telemetry.sensor if self.telemetry else None
        speed = sensor.true_airspeed() if sensor is not None else None
        if speed is not None:
            return speed
        gps = self.gps
        return None if gps is None else airspeed((gps.vel_east, gps.vel_north), self.wind.value)

    def smoothed_airspeed(self) -> float | None:
        """The air data's true airspeed averaged over the wind's time constant (an
        exponential moving average in time), where the autopilot reports one, else
        `airspeed()`. A leg timed at one instant's reading is off by that instant's gust:
        on JSBSim the reading spreads 0.9 m/s about the commanded 22 (docs/benchmarks.md),
        an upwind time ~10 % for 1 m/s."""
        mean = self.air_data_airspeed()
        return mean if mean is not None else self.airspeed()

    def air_data_airspeed(self) -> float | None:
        """The air data's true airspeed averaged like the wind; None where the autopilot
        reports none (`smoothed_airspeed` then falls back on the GPS velocity less the
        wind, which moves with every turn)."""
        average = self._airspeed
        return None if average is None or average.value is None else average.value[0]

    def _average_airspeed(self, telemetry: Telemetry, aircraft_s: float) -> None:
        sensor = telemetry.sensor
        speed = sensor.true_airspeed() if sensor is not None else None
        if speed is None or not math.isfinite(speed):
            return
        if self._airspeed is None:
            self._airspeed = TimeAverage(self.wind.time_constant_s)
        self._airspeed.add((speed,), aircraft_s)

    def lost(self, now: float) -> bool:
        """True while no telemetry has arrived for LINK_LOST_S (or none ever did)."""
        return self.telemetry_at is None or now - self.telemetry_at > LINK_LOST_S

    def awaiting_first(self, now: float) -> bool:
        """True while a module that just started has had no telemetry yet, for less than
        LINK_LOST_S: its link is not known lost, only not heard yet."""
        return (
            self.telemetry_at is None
            and self.started_at is not None
            and now - self.started_at <= LINK_LOST_S
        )

    def check(self, now: float) -> None:
        """Say so once when telemetry that was flowing stops."""
        if self.telemetry_at is None or self._said_lost or not self.lost(now):
            return
        self._said_lost = True
        self.outages += 1
        text = f"error: autopilot link lost: no telemetry for over {LINK_LOST_S:g} s"
        self.say(StatusKind.LINK_LOST, text, now)
