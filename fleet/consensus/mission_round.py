"""One mission's distributed target assignment, as one UAV sees it (thesis 4.4, hardened).

The thesis assumed lossless links and every UAV in range. Here:

* the team is the one the ground named, less the UAVs not alive (liveliness);
* a UAV commits as soon as it holds the result of every live teammate, or at the
  mission's deadline with whatever it holds (missing results are fetched by query
  first, by the caller, every `FETCH_INTERVAL` seconds);
* a committed assignment seen from a teammate is adopted as is: "first committed
  wins" makes late joiners and restarted UAVs fall in line, and closes the window in
  which two UAVs could decide on different inputs;
* every commitment carries the digest of the exact results it used, so the ground can
  confirm agreement or name who disagreed.

Pure: no I/O, time comes in as `now`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fleet.consensus.assignment import greedy_assign, results_digest
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult

FETCH_INTERVAL = 1.0


@dataclass
class MissionRound:
    targets: MissionTargets
    own_id: int
    started: float
    results: dict[int, UavResult] = field(default_factory=dict)
    committed: AssignmentReport | None = None
    last_fetch: float | None = None

    @property
    def mission(self) -> int:
        return self.targets.mission

    @property
    def deadline(self) -> float:
        return self.started + self.targets.deadline_s

    def add_result(self, result: UavResult) -> bool:
        """Keep a teammate's (or our own) result; False if it is not for this round."""
        if result.mission != self.mission or result.uav not in self.targets.team:
            return False
        if len(result.times) != len(self.targets.targets):
            return False
        self.results[result.uav] = result
        return True

    def expected(self, alive: set[int]) -> set[int]:
        """Teammates whose results this UAV still waits for or holds."""
        return {uav for uav in self.targets.team if uav in alive or uav == self.own_id}

    def missing(self, alive: set[int]) -> set[int]:
        return self.expected(alive) - self.results.keys()

    def ready(self, now: float, alive: set[int]) -> bool:
        if self.committed is not None or self.own_id not in self.results:
            return False
        return not self.missing(alive) or now >= self.deadline

    def should_fetch(self, now: float, alive: set[int]) -> bool:
        """Time to query the results we have not heard published."""
        if self.committed is not None or not self.missing(alive):
            return False
        if self.own_id not in self.results:
            return False
        return self.last_fetch is None or now - self.last_fetch >= FETCH_INTERVAL

    def decide(self, alive: set[int]) -> AssignmentReport:
        """Run the greedy on the results of the live teammates held now, and commit."""
        used = {
            uav: result.times
            for uav, result in self.results.items()
            if uav in alive or uav == self.own_id
        }
        outcome = greedy_assign(used, len(self.targets.targets))
        target = outcome.pairs.get(self.own_id)
        own_times = self.results[self.own_id].times
        self.committed = AssignmentReport(
            mission=self.mission,
            uav=self.own_id,
            target=target,
            pairs={str(uav): index for uav, index in sorted(outcome.pairs.items())},
            unassigned=tuple(outcome.unassigned_targets),
            team=tuple(sorted(used)),
            digest=results_digest(used),
            eta_s=own_times[target] if target is not None else None,
        )
        return self.committed

    def adopt(self, report: AssignmentReport) -> AssignmentReport | None:
        """Take a teammate's committed assignment as ours; None if we committed already."""
        if self.committed is not None or report.mission != self.mission:
            return None
        target = report.pairs.get(str(self.own_id))
        own = self.results.get(self.own_id)
        self.committed = AssignmentReport(
            mission=self.mission,
            uav=self.own_id,
            target=target,
            pairs=dict(report.pairs),
            unassigned=report.unassigned,
            team=report.team,
            digest=report.digest,
            eta_s=own.times[target] if own is not None and target is not None else None,
        )
        return self.committed
