"""An arrival hidden by a link outage, read from the telemetry on either side of it.

The autopilot moves on from the target waypoint only on reaching it (or when told to
track another waypoint). During an outage the module sees neither the arrival nor the
waypoints the autopilot went through after it: when the link comes back, the autopilot
may track the target's `next`, or the one after it, or any later one. Which waypoint
it tracks then says little; where the aircraft was says more. The last fix before the
outage, the first after it, and the autopilot's own clock in each say whether the
aircraft could have flown through the target's acceptance radius meanwhile: the path
from the one fix to the target's radius and on to the other is no longer than it could
fly in that time (`passed_target`). An aircraft turned away by another ground station
far from the target could not have; one that held its course through it could.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fleet.geo.mercator import distance_m
from fleet.mission.messages import Target
from fleet.piccolo.telemetry import GpsBlock

#: The aircraft flew at most this much faster than the faster of the two fixes says
#: (a gust, a dive), plus `_SPEED_MARGIN_MPS`.
_SPEED_SLACK = 1.25
_SPEED_MARGIN_MPS = 5.0
_MS_PER_WEEK = 7 * 24 * 3600 * 1000


@dataclass
class FixHistory:
    """The latest GPS fix, and the last one before the latest link outage."""

    latest: GpsBlock | None = None
    before_outage: GpsBlock | None = None
    _outages: int = 0  #: the link's outage count at the latest fix

    def on_fix(self, gps: GpsBlock | None, outages: int) -> None:
        if gps is None:
            return
        if outages != self._outages and self.latest is not None:
            self.before_outage = self.latest
        self._outages = outages
        self.latest = gps

    def fresh_since(self, outages: int) -> bool:
        """A fix arrived since the link's `outages`-th outage ended."""
        return self.latest is not None and self._outages == outages


def autopilot_ms(gps: GpsBlock) -> int:
    """The autopilot's GPS time of the fix (ms)."""
    return gps.gps_week * _MS_PER_WEEK + gps.gps_time_of_week_ms


def passed_target(before: GpsBlock, after: GpsBlock, target: Target, radius: float) -> bool:
    """The aircraft could have come within `radius` of `target` between the two fixes."""
    elapsed = (autopilot_ms(after) - autopilot_ms(before)) / 1000.0
    if elapsed <= 0.0:
        return False
    fastest = max(math.hypot(g.vel_north, g.vel_east) for g in (before, after))
    reach = (fastest * _SPEED_SLACK + _SPEED_MARGIN_MPS) * elapsed
    there = max(0.0, distance_m((before.lat, before.lon), (target.lat, target.lon)) - radius)
    back = max(0.0, distance_m((target.lat, target.lon), (after.lat, after.lon)) - radius)
    return there + back <= reach
