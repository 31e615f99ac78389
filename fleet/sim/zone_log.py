"""The simulator's own record of no-fly zone incursions: the ground truth of a flight.

Every aircraft's simulated position, at every integration step, is checked against the
no-fly zones the simulator was given (`fleet sim --no-fly`, or the scenario's
`no_fly`): entering a zone is logged as an error (which aircraft, which zone, where,
when) and counted, leaving it as a warning with how long it was inside. The check is
the simulator's alone: it holds whatever the onboard or the ground believe.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

from fleet.geo.mercator import MercatorProjection
from fleet.geo.zones import Ring, point_in_ring, ring_to_local
from fleet.mission.messages import NoFlyZone
from fleet.mission.no_fly import zone_label

logger = logging.getLogger(__name__)

__all__ = ["IncursionLog"]


@dataclass
class IncursionLog:
    """Incursions of one aircraft (on its simulator's local plane)."""

    piccolo_id: int
    projection: MercatorProjection
    zones: Sequence[NoFlyZone]
    #: Incursions so far: each entry into a zone counts once.
    incursions: int = 0
    _rings: list[Ring] = field(init=False)
    _boxes: list[tuple[float, float, float, float]] = field(init=False)
    _inside: dict[int, int] = field(default_factory=dict)  #: zone -> entered at (ms)

    def __post_init__(self) -> None:
        self._rings = [ring_to_local(self.projection, zone.ring) for zone in self.zones]
        self._boxes = [
            (min(x for x, _ in r), min(y for _, y in r), max(x for x, _ in r), max(y for _, y in r))
            for r in self._rings
        ]

    def check(self, x: float, y: float, time_ms: int) -> None:
        """The aircraft is at (x, y) local metres at simulated `time_ms`."""
        for index, ring in enumerate(self._rings):
            x0, y0, x1, y1 = self._boxes[index]
            inside = x0 <= x <= x1 and y0 <= y <= y1 and point_in_ring((x, y), ring)
            entered = self._inside.get(index)
            if inside and entered is None:
                self._inside[index] = time_ms
                self.incursions += 1
                lat, lon = self.projection.to_latlon(x, y)
                logger.error(
                    "no-fly incursion: UAV %d entered %s at %.6f, %.6f (simulated %.1f s)",
                    self.piccolo_id,
                    zone_label(index, self.zones[index]),
                    lat,
                    lon,
                    time_ms / 1000.0,
                )
            elif not inside and entered is not None:
                del self._inside[index]
                logger.warning(
                    "no-fly incursion: UAV %d left %s after %.1f s inside",
                    self.piccolo_id,
                    zone_label(index, self.zones[index]),
                    (time_ms - entered) / 1000.0,
                )
