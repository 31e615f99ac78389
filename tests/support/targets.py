"""Mission targets for the fleet tests and benchmarks."""

from __future__ import annotations

import math
import random

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
