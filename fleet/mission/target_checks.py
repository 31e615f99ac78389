"""Target sets nobody should fly: checks on a mission's targets as a whole.

Each target's own ranges are the targets file's concern (`fleet.mission.targets_file`);
these look at the set against itself and against the team: two targets within the
acceptance radius of each other (one arrival would count for both; two UAVs would be
sent to one point), a target farther than the team's aircraft can fly from every team
UAV, and a target on the far side of the Earth from the team (where the planner's local
map does not hold). Each problem names its targets and says why; the ground refuses
the mission unless the operator overrides (`ground-cli send-targets --force`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

from fleet.geo.great_circle import EARTH_RADIUS_M, great_circle_m
from fleet.mission.messages import Target

#: Within this distance (m) of its target by telemetry, a UAV has reached it (the
#: onboard's acceptance radius): the autopilot's own (60 m in the simulator) plus what
#: the aircraft flies between two telemetry packets at top speed and 5 Hz.
REACHED_RADIUS_M = 75.0
#: How far from the nearest team UAV a target may be by default: an hour and a half at
#: a Piccolo-class cruise of 22 m/s, well within the endurance of such an aircraft.
DEFAULT_MAX_REACH_M = 120_000.0
#: Beyond a quarter of the Earth's circumference a target is on the far side of it.
FAR_SIDE_M = EARTH_RADIUS_M * math.pi / 2.0


class ProblemKind(StrEnum):
    DUPLICATE = "duplicate"  #: within the acceptance radius of another target
    BEYOND_REACH = "beyond_reach"  #: farther than the team's aircraft can fly
    FAR_SIDE = "far_side"  #: on the far side of the Earth from the team


@dataclass(frozen=True)
class TargetProblem:
    kind: ProblemKind
    targets: tuple[int, ...]  #: the target indices it concerns
    detail: str

    def __str__(self) -> str:
        which = " and ".join(str(index) for index in self.targets)
        return f"target{'s' if len(self.targets) > 1 else ''} {which}: {self.detail}"


def target_set_problems(
    targets: Sequence[Target],
    positions: Mapping[int, tuple[float, float]],
    max_reach_m: float = DEFAULT_MAX_REACH_M,
) -> list[TargetProblem]:
    """Every problem of `targets` as a set, given the team's known `positions` (Piccolo
    ID -> latitude, longitude; UAVs with no fix yet left out). Deterministic order."""
    return [*_duplicates(targets), *_reach(targets, positions, max_reach_m)]


def _duplicates(targets: Sequence[Target]) -> list[TargetProblem]:
    problems = []
    for i, first in enumerate(targets):
        for j in range(i + 1, len(targets)):
            second = targets[j]
            apart = great_circle_m(first.lat, first.lon, second.lat, second.lon)
            if apart < REACHED_RADIUS_M:
                problems.append(
                    TargetProblem(
                        ProblemKind.DUPLICATE,
                        (i, j),
                        f"{apart:.0f} m apart, within the {REACHED_RADIUS_M:g} m acceptance "
                        "radius: one arrival would count for both",
                    )
                )
    return problems


def _reach(
    targets: Sequence[Target], positions: Mapping[int, tuple[float, float]], max_reach_m: float
) -> list[TargetProblem]:
    if not positions:
        return []  # no fix yet: nothing to measure against
    problems = []
    for index, target in enumerate(targets):
        nearest, uav = min(
            (great_circle_m(lat, lon, target.lat, target.lon), uav)
            for uav, (lat, lon) in sorted(positions.items())
        )
        if nearest > FAR_SIDE_M:
            problems.append(
                TargetProblem(
                    ProblemKind.FAR_SIDE,
                    (index,),
                    f"{nearest / 1000:.0f} km from the nearest team UAV ({uav}): on the far "
                    "side of the Earth",
                )
            )
        elif nearest > max_reach_m:
            problems.append(
                TargetProblem(
                    ProblemKind.BEYOND_REACH,
                    (index,),
                    f"{nearest / 1000:.0f} km from the nearest team UAV ({uav}), beyond the "
                    f"{max_reach_m / 1000:g} km the team can fly",
                )
            )
    return problems
