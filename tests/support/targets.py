"""Mission targets for the fleet tests and benchmarks."""

from __future__ import annotations

import math
import random
from collections.abc import Iterable
from pathlib import Path

from fleet.geo.mercator import MercatorProjection
from fleet.launch.ring import GENERATED_CENTRE
from fleet.mission.messages import Target


def ring_targets(count: int, seed: int) -> tuple[Target, ...]:
    rng = random.Random(seed)
    projection = MercatorProjection(*GENERATED_CENTRE)
    points = []
    for _ in range(count):
        bearing, distance = rng.uniform(0, 2 * math.pi), rng.uniform(500.0, 2500.0)
        lat, lon = projection.to_latlon(distance * math.sin(bearing), distance * math.cos(bearing))
        points.append(Target(lat, lon, 600.0))
    return tuple(points)


#: Nine targets for the `windy` scenario, local metres east/north of its first UAV's
#: start: three about each UAV, upwind, downwind and across the wind of it.
WINDY_NINE = (
    (-3000, 1000), (-1000, 3500), (2500, 2500),
    (3000, -7000), (5000, -4500), (1500, -3500),
    (1000, 11000), (-2500, 10500), (-3500, 7000),
)  # fmt: skip


def targets_csv(
    path: Path, origin: tuple[float, float], points: Iterable[tuple[float, float]]
) -> Path:
    """`points`, local metres east/north of `origin` (lat, lon), written to `path` as a
    targets CSV (lat, lon, alt 600 m)."""
    projection = MercatorProjection(*origin)
    rows = ["lat,lon,alt"]
    for x, y in points:
        lat, lon = projection.to_latlon(x, y)
        rows.append(f"{lat:.7f},{lon:.7f},600")
    path.write_text("\n".join(rows) + "\n")
    return path


def windy_nine_csv(path: Path) -> Path:
    """`WINDY_NINE` written to `path` as a targets CSV."""
    from fleet.sim.scenario import shipped_scenario

    first = shipped_scenario("windy").uavs[0]
    return targets_csv(path, (first.lat, first.lon), WINDY_NINE)
