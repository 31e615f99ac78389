"""Target-to-target flight times: closed form, from the mission alone.

A UAV's approach time to each target comes from its own model (its result); the time
from one target to the next does not depend on the aircraft's state, only on the two
targets, so every UAV computes it identically from the mission it was sent, and nothing
more needs publishing for a queue (docs/queues.md). The leg is the great-circle distance
flown at `LEG_SPEED_MPS`, plus `LEG_TURN_S` for the turn at the target the aircraft
passes over: a closed form, not the approach model, which is too slow for T x T legs
(200 targets: 39,800 legs).

Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from fleet.mission.messages import Target

#: The airspeed (m/s) a leg is flown at: the simulated aircraft's cruise.
LEG_SPEED_MPS = 22.0
#: Seconds added to every leg for the turn over the target just reached: half a
#: standard-rate 360-degree turn (a 180-degree reversal at 3 deg/s takes 60 s; the mean
#: turn is about a quarter of that, rounded up).
LEG_TURN_S = 15.0
_EARTH_RADIUS_M = 6_371_008.8


def great_circle_m(a: Target, b: Target) -> float:
    """Metres along the great circle between two targets (haversine)."""
    lat1, lat2 = math.radians(a.lat), math.radians(b.lat)
    dlat = lat2 - lat1
    dlon = math.radians(b.lon - a.lon)
    h = math.sin(dlat / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin(dlon / 2) ** 2
    return 2 * _EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(h)))


def leg_times(
    targets: Sequence[Target], speed_mps: float = LEG_SPEED_MPS, turn_s: float = LEG_TURN_S
) -> list[list[float]]:
    """`legs[i][j]`: seconds from target i to target j (0 on the diagonal)."""
    count = len(targets)
    legs = [[0.0] * count for _ in range(count)]
    for i in range(count):
        for j in range(i + 1, count):
            legs[i][j] = legs[j][i] = great_circle_m(targets[i], targets[j]) / speed_mps + turn_s
    return legs
