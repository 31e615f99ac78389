"""Checks of what a UAV hears about a mission, before it uses it: a teammate's
assignment report (its pairs and queues), the mission's targets; and a report's
predicted arrival at one target.

Pure: no I/O.
"""

from __future__ import annotations

import functools
import math

from fleet.mission.messages import AssignmentReport, MissionTargets
from fleet.mission.no_fly import mission_zone_problem
from fleet.mission.targets_file import TargetsFileError, encode_targets


def assignment_problem(report: AssignmentReport, targets: MissionTargets) -> str | None:
    """Why a teammate's assignment cannot be this mission's (None if it can be).

    The schema bounds each index by MAX_TARGETS only; here every pair must name a UAV of
    the mission's team and a target of this mission, no target twice, so that a hostile or
    corrupt report is refused whole instead of being indexed, flown or re-planned.
    """
    count = len(targets.targets)
    team = team_set(targets.team)
    pairs = report.pairs
    # A set comparison in C checks every pair's UAV at once (the ground checks N reports
    # of N pairs per mission, a UAV every re-plan it hears).
    if not team >= pairs.keys() or (pairs and max(pairs.values()) >= count):
        for uav, index in pairs.items():  # name the first bad pair
            if uav not in team:
                return f"pair {uav}: not a UAV of mission {targets.mission}'s team"
            if index >= count:
                return f"UAV {uav}'s target {index}: mission {targets.mission} has {count}"
    if len(set(pairs.values())) != len(pairs):
        return "two UAVs paired with the same target"
    if report.target is not None and report.target >= count:
        return f"target {report.target}: mission {targets.mission} has {count}"
    if report.unassigned and max(report.unassigned) >= count:
        return f"an unassigned target beyond mission {targets.mission}'s {count}"
    if not team.issuperset(report.team):
        return f"results of UAVs outside mission {targets.mission}'s team"
    return queues_problem(report, targets, team)


def queues_problem(
    report: AssignmentReport, targets: MissionTargets, team: frozenset[int]
) -> str | None:
    """Why a report's queues cannot be this mission's (None if they can be): each a team
    UAV's, of this mission's targets, no target in two places."""
    count = len(targets.targets)
    queued = [t for queue in report.queues.values() for t in queue]
    if not team >= report.queues.keys():
        return f"a queue of a UAV outside mission {targets.mission}'s team"
    if queued and max(queued) >= count:
        return f"a queued target beyond mission {targets.mission}'s {count}"
    if len(set(queued)) != len(queued):
        return "a target queued twice"
    for uav, queue in report.queues.items():
        if queue and report.pairs.get(uav) != queue[0]:
            return f"UAV {uav}'s queue does not start with its target"
    return None


def predicted_arrival(report: AssignmentReport, uav: int, target: int) -> float | None:
    """When `report` predicts `uav` reaches `target` (s after the results), if it says."""
    queue, arrivals = report.queues.get(uav, ()), report.arrivals.get(uav, ())
    if target in queue and len(arrivals) == len(queue):
        return arrivals[queue.index(target)]
    return report.eta_s if report.target == target else None


def targets_problem(targets: MissionTargets) -> str | None:
    """Why a mission's targets cannot be flown (None if they can be)."""
    try:
        encode_targets(targets.targets, source=f"mission {targets.mission}")
    except TargetsFileError as error:
        return f"target {error.index}: {error.problem}" if targets.targets else error.problem
    if not math.isfinite(targets.deadline_s) or targets.deadline_s <= 0:
        return f"deadline {targets.deadline_s!r} s is not a positive number"
    return mission_zone_problem(targets.zones, targets.targets)


@functools.lru_cache(maxsize=8)
def team_set(team: tuple[int, ...]) -> frozenset[int]:
    """A team's Piccolo IDs (a few recent teams are kept)."""
    return frozenset(team)
