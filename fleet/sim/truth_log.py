"""The simulator's own record of where each aircraft truly was: the ground truth of a flight.

`fleet sim --truth-log FILE` writes every aircraft's position, from the simulator's own
state (not its telemetry, not what an onboard or the ground believe), every
`TRUTH_PERIOD_MS` of simulated time, as CSV lines `sim_ms,uav,lat,lon,alt`. A benchmark
reads it back (`read_truth`) to tell which targets were truly flown and by whom
(`closest_approaches`), whatever the fleet reported.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TextIO

from fleet.geo.mercator import MercatorProjection
from fleet.geo.zones import distance_to_segment

logger = logging.getLogger(__name__)

__all__ = ["TRUTH_PERIOD_MS", "TruthLog", "TruthSample", "closest_approaches", "read_truth"]

#: Simulated time between two samples of one aircraft: at 25 m/s, 5 m apart.
TRUTH_PERIOD_MS = 200
HEADER = "sim_ms,uav,lat,lon,alt"


@dataclass(frozen=True)
class TruthSample:
    sim_ms: int
    uav: int
    lat: float
    lon: float
    alt: float


@dataclass
class TruthLog:
    """Writes samples to `out` (line-buffered, so a killed simulator leaves what it had)."""

    out: TextIO
    period_ms: int = TRUTH_PERIOD_MS
    _next_ms: dict[int, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        print(HEADER, file=self.out)

    @classmethod
    def to_file(cls, path: str) -> TruthLog:
        """A log written to `path` (replaced), line-buffered: a simulator killed by a
        signal leaves every line it had. `close` closes it."""
        return cls(open(path, "w", buffering=1, encoding="utf-8"))

    def close(self) -> None:
        self.out.close()

    def note(self, uav: int, sim_ms: int, position: tuple[float, float, float]) -> None:
        """The aircraft `uav` is at `position` (lat, lon, alt) at simulated `sim_ms`."""
        if sim_ms < self._next_ms.get(uav, 0):
            return
        self._next_ms[uav] = sim_ms + self.period_ms
        lat, lon, alt = position
        print(f"{sim_ms},{uav},{lat:.7f},{lon:.7f},{alt:.1f}", file=self.out)


def read_truth(lines: Iterable[str], source: str = "truth log") -> list[TruthSample]:
    """The samples of a truth log; a malformed line is dropped with a warning naming it."""
    samples: list[TruthSample] = []
    for number, line in enumerate(lines, 1):
        text = line.strip()
        if not text or text == HEADER:
            continue
        try:
            sim_ms, uav, lat, lon, alt = text.split(",")
            samples.append(TruthSample(int(sim_ms), int(uav), float(lat), float(lon), float(alt)))
        except ValueError:
            # A simulator killed mid-line leaves a partial last line.
            logger.warning(
                "%s line %d: expected sim_ms,uav,lat,lon,alt, got %r", source, number, text
            )
    return samples


def closest_approaches(
    samples: Sequence[TruthSample], targets: Sequence[tuple[float, float]]
) -> dict[int, list[float]]:
    """UAV id -> its closest horizontal approach (m) to each target, along its track taken
    as straight segments between consecutive samples (so a pass between two samples counts)."""
    if not samples or not targets:
        return {}
    projection = MercatorProjection(targets[0][0], targets[0][1])
    points = [projection.to_xy(lat, lon) for lat, lon in targets]
    tracks: dict[int, list[tuple[float, float]]] = {}
    for sample in sorted(samples, key=lambda s: (s.uav, s.sim_ms)):
        tracks.setdefault(sample.uav, []).append(projection.to_xy(sample.lat, sample.lon))
    nearest: dict[int, list[float]] = {}
    for uav, track in tracks.items():
        segments = list(itertools.pairwise(track)) or [(track[0], track[0])]
        nearest[uav] = [min(distance_to_segment(p, a, b) for a, b in segments) for p in points]
    return nearest
