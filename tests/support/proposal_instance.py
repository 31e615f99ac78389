"""The small instance the proposal tests share: mission 9, UAVs 3 and 5, six targets
(min-sum), each UAV's result drawn from one seed; and a plan better than the baseline's
local search on it, by the same scorer."""

from __future__ import annotations

import random

from fleet.geo.mercator import MercatorProjection
from fleet.mission.messages import MissionTargets, Target, UavResult
from fleet.mission.objective import Objective

PROJECTION = MercatorProjection(35.72, -120.76)
#: The optimum of this instance (found by enumerating every plan): better than the
#: baseline's local search, by the same scorer.
BETTER = {3: (4, 0), 5: (2, 1, 5, 3)}


def mission_and_results(
    proposals_s: float = 20.0, proposers: tuple[int, ...] = ()
) -> tuple[MissionTargets, list[UavResult]]:
    """The mission and UAV 3's and 5's results (in that order)."""
    rng = random.Random(1)
    points = [(rng.uniform(-4000, 4000), rng.uniform(-4000, 4000)) for _ in range(6)]
    targets = tuple(Target(*PROJECTION.to_latlon(x, y), 600.0) for x, y in points)
    mission = MissionTargets(
        mission=9,
        team=(3, 5),
        targets=targets,
        objective=Objective.MIN_SUM,
        deadline_s=30.0,
        proposals_s=proposals_s,
        proposers=proposers,
    )
    results = [
        UavResult(
            9,
            uav,
            tuple(rng.uniform(60, 400) for _ in points),
            airspeed=22.0,
            wind_east=8.0,
            wind_north=2.0,
            lat=35.72,
            lon=-120.76,
        )
        for uav in (3, 5)
    ]
    return mission, results
