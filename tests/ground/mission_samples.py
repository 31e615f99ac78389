"""Missions and sessions for the ground's mission tests (ids, following, outcome)."""

from __future__ import annotations

from collections.abc import Callable

from fleet.mission.messages import MissionTargets, Target

TIMEOUT_S = 1.0
TARGETS = (Target(42.36, -71.09, 120.0), Target(42.365, -71.10, 110.0))
OTHER_TARGETS = (Target(42.37, -71.08, 150.0),)


def mission(
    m: int, targets: tuple[Target, ...] = TARGETS, team: tuple[int, ...] = (7, 8)
) -> MissionTargets:
    return MissionTargets(mission=m, team=team, targets=targets)


def maker(targets: tuple[Target, ...]) -> Callable[[int], MissionTargets]:
    def make(m: int) -> MissionTargets:
        return mission(m, targets)

    return make
