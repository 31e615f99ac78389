"""Telling the ground when this aircraft is inside one of its mission's no-fly zones.

Each GPS fix is checked against the current mission's zones (each on the local plane
of its own first vertex, as fleet.mission.no_fly checks them). Entering a zone is a
`ZONE_INCURSION` status (an error, on the ground's status box and `watch`); leaving it
a `ZONE_LEFT`. The routes keep out of the zones with a margin, so an incursion means
the aircraft left its route (a gust, the operator, an autopilot fault): the ground must
hear of it whatever the onboard is doing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fleet.geo.mercator import MercatorProjection
from fleet.geo.zones import Ring, point_in_ring, ring_to_local
from fleet.mission.messages import NoFlyZone
from fleet.mission.no_fly import zone_label
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock
from onboard.state_report import Say


@dataclass
class ZoneWatch:
    say: Say
    _zones: tuple[NoFlyZone, ...] = ()
    _planes: list[tuple[MercatorProjection, Ring]] = field(default_factory=list)
    _inside: set[int] = field(default_factory=set)

    def check(
        self, gps: GpsBlock | None, zones: tuple[NoFlyZone, ...], mission: int | None, now: float
    ) -> None:
        """The latest fix against `zones` (the current mission's: none without one)."""
        if zones is not self._zones:
            self._zones, self._inside = zones, set()
            self._planes = []
            for zone in zones:
                projection = MercatorProjection(*zone.ring[0])
                self._planes.append((projection, ring_to_local(projection, zone.ring)))
        if gps is None or not self._planes:
            return
        for index, (projection, ring) in enumerate(self._planes):
            try:
                inside = point_in_ring(projection.to_xy(gps.lat, gps.lon), ring)
            except ValueError:
                continue  # a fix the projection refuses (NaN): the link watch says so
            label = zone_label(index, self._zones[index])
            if inside and index not in self._inside:
                self._inside.add(index)
                text = f"error: inside {label} at {gps.lat:.6f}, {gps.lon:.6f}"
                self.say(StatusKind.ZONE_INCURSION, text, now, mission=mission)
            elif not inside and index in self._inside:
                self._inside.discard(index)
                self.say(StatusKind.ZONE_LEFT, f"left {label}", now, mission=mission)
