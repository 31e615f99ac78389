"""This UAV's own proposed plan, where it has the CPU (`fleet-onboard --propose`).

A mission that names this UAV among its proposers (`MissionTargets.proposers`) and has a
proposal window: once this UAV holds every team UAV's result, it solves the queues with
PyVRP (`fleet.solver.proposer`, off the main loop: a min-max solve takes seconds) and
publishes the proposal on its own key (`mission/{m}/proposal/{id}`), signed with its
own key like all it writes. Its teammates verify and score it as any proposal
(`fleet.consensus.proposal`); so does this UAV. A solve that fails (PyVRP missing, bad
input) is said once and changes nothing: the team decides on what it holds.

Whether it will propose is said beforehand, in this UAV's result for the mission
(`UavResult.proposes`, `will_propose`): its teammates then wait for no proposal of a
named UAV that says it will not (started without `--propose`, or without PyVRP), and
decide as soon as every result is in, all alike (fleet.consensus.proposal).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from fleet.consensus.mission_round import MissionRound
from fleet.errors import FleetError
from fleet.mission.messages import MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from fleet.mission.status_kind import StatusKind
from fleet.solver.proposer import proposal_for
from fleet.solver.pyvrp_plan import solver_available
from onboard.state_report import Say

log = logging.getLogger(__name__)

#: Solves a proposal: (the mission, the team's results, the proposer) -> the proposal.
Solve = Callable[[MissionTargets, dict[int, UavResult], int], PlanProposal]
#: Runs a solve off the main loop (a thread by default; the tests run it at once).
Run = Callable[[Callable[[], None]], None]


def _in_thread(work: Callable[[], None]) -> None:
    threading.Thread(target=work, name="plan-proposer", daemon=True).start()


@dataclass
class PlanProposer:
    uav_id: int
    say: Say
    solve: Solve = proposal_for
    run: Run = _in_thread
    #: Whether its solver can be imported here (PyVRP): without it, it proposes nothing.
    solvable: bool = field(default_factory=solver_available)
    #: The mission whose proposal is being solved or was, once each.
    _mission: int | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _done: PlanProposal | str | None = None  #: the proposal, or why none

    def tick(self, mission_round: MissionRound, now: float) -> PlanProposal | None:
        """Start the solve once this UAV should propose for `mission_round` and holds
        every team UAV's result; the proposal once it is solved (once), else None."""
        targets = mission_round.targets
        if self._mission == targets.mission:
            return self._collect(mission_round, now)
        if not self._should_propose(mission_round):
            return None
        self._mission = targets.mission
        results = dict(mission_round.results)
        with self._lock:
            self._done = None

        def work() -> None:
            done: PlanProposal | str
            try:
                done = self.solve(targets, results, self.uav_id)
            except (FleetError, ValueError) as error:  # SolverUnavailable is a FleetError
                done = str(error)
            with self._lock:
                self._done = done

        log.info("mission %d: solving this UAV's proposal", targets.mission)
        self.run(work)
        return self._collect(mission_round, now)

    def will_propose(self, targets: MissionTargets) -> bool:
        """Whether this UAV will propose a plan for the mission `targets` (what its
        result says, `UavResult.proposes`): named, a window and an objective to propose
        for, and its solver here."""
        return (
            self.solvable
            and self.uav_id in targets.proposers
            and targets.proposals_s > 0.0
            and targets.objective is not Objective.GREEDY
        )

    def _should_propose(self, mission_round: MissionRound) -> bool:
        return (
            self.will_propose(mission_round.targets)
            and mission_round.committed is None
            and mission_round.team <= mission_round.results.keys()
        )

    def _collect(self, mission_round: MissionRound, now: float) -> PlanProposal | None:
        with self._lock:
            done, self._done = self._done, None
        if done is None:
            return None
        mission = mission_round.targets.mission
        if isinstance(done, str):
            why = f"mission {mission}: no plan proposed: {done}"
            self.say(StatusKind.WARNING, why, now, mission=mission)
            return None
        if mission_round.committed is not None:
            log.warning("mission %d: this UAV's proposal came after the decision", mission)
            return None
        return done
