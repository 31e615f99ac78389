"""The epoch-0 report a UAV publishes for a greedy round over given approach times: the
base the re-plan tests derive later epochs from."""

from __future__ import annotations

from collections.abc import Mapping

from fleet.consensus.assignment import greedy_assign, results_digest
from fleet.mission.messages import AssignmentReport


def greedy_report(times: Mapping[int, tuple[float | None, ...]], uav: int = 74) -> AssignmentReport:
    """UAV `uav`'s report of mission 1's greedy round over `times` (UAV -> times)."""
    outcome = greedy_assign(times, len(next(iter(times.values()))))
    return AssignmentReport(
        mission=1,
        uav=uav,
        target=outcome.pairs.get(uav),
        pairs=dict(outcome.pairs),
        unassigned=outcome.unassigned_targets,
        team=tuple(sorted(times)),
        digest=results_digest(times),
    )
