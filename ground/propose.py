"""The ground's proposed plan: solved by PyVRP from the results the team exchanged.

`send-targets --propose` sends the mission with a proposal window (`proposals_s`):
every UAV holding every teammate's result waits for a proposal that long before it
decides. The ground waits for the team's results, solves the queues from them with
PyVRP as any proposer does (`fleet.solver.proposer`) and publishes a `PlanProposal`,
signed like every command of the ground. Every UAV verifies and scores it, and adopts it
only if it is valid and better than the baseline (fleet.consensus.proposal). The page
(`ground-cli gui`, "propose a plan") proposes through the same `propose_when_results`,
and names UAV proposers (`send-targets --proposers`, the page's "UAV proposers" field)
through the same `named_proposers`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MISSION_MANAGER, MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from fleet.solver.proposer import proposal_for
from fleet.solver.pyvrp_plan import SolverUnavailable
from fleet.transport.bus import Bus
from ground.mission_follower import MissionFollower

__all__ = [
    "DEFAULT_WINDOW_S",
    "ProposalAttempt",
    "named_proposers",
    "proposal_window",
    "propose",
    "propose_when_results",
]

log = logging.getLogger(__name__)

#: How long (s) the UAVs wait for the ground's proposal by default.
DEFAULT_WINDOW_S = 20.0


def propose(
    bus: Bus, space: KeySpace, targets: MissionTargets, results: dict[int, UavResult]
) -> tuple[PlanProposal, float]:
    """Solve and publish the ground's proposal; (the proposal, CPU seconds it took)."""
    started = time.process_time()
    proposal = proposal_for(targets, results, MISSION_MANAGER)
    spent = time.process_time() - started
    bus.publish(space.mission_proposal(targets.mission), proposal)
    log.info("mission %d: plan proposed (%.2f s of CPU)", targets.mission, spent)
    return proposal, spent


def named_proposers(propose: bool, uavs: Sequence[int], team: Sequence[int]) -> tuple[int, ...]:
    """Who a mission sent to `team` names as its proposers: the UAVs that propose a plan
    on board (each started with `--propose`), and the ground too when it proposes as
    well. The ground proposing alone names none: the UAVs then take the ground's
    proposal alone. ValueError for a UAV outside the team: it holds no round to solve
    from, and the UAVs would refuse its plan."""
    outside = [uav for uav in uavs if uav not in team]
    if outside:
        which = ", ".join(map(str, outside))
        raise ValueError(f"UAV proposer {which} is not in the team ({', '.join(map(str, team))})")
    named = tuple(dict.fromkeys(uavs))
    return (*named, MISSION_MANAGER) if named and propose else named


def proposal_window(objective: Objective, deadline_s: float) -> tuple[float, float]:
    """(deadline_s, proposals_s) of a mission the ground proposes a plan for: the UAVs
    wait `DEFAULT_WINDOW_S` for it, and decide at their deadline whatever they hold, so
    the deadline comes after the window. ValueError for the greedy (no score to rank a
    proposal by)."""
    if objective is Objective.GREEDY:
        raise ValueError("proposing a plan needs the objective min-sum or min-max")
    return max(deadline_s, DEFAULT_WINDOW_S + 5.0), DEFAULT_WINDOW_S


@dataclass(frozen=True)
class ProposalAttempt:
    """The ground's proposal put on the bus, or why none was."""

    proposal: PlanProposal | None
    cpu_s: float | None = None
    reason: str | None = None  #: why no proposal was put


def propose_when_results(
    bus: Bus,
    space: KeySpace,
    message: MissionTargets,
    follower: MissionFollower,
    stop: threading.Event | None = None,
) -> ProposalAttempt:
    """Wait (within the mission's proposal window) for every team UAV's result, then
    solve and publish the ground's proposal. Blocking; `stop` set ends the wait (within
    a second) with no proposal."""
    team = set(message.team)
    stopped = stop or threading.Event()
    heard = follower.wait_until(
        lambda: stopped.is_set() or team <= follower.results.keys(),
        message.proposals_s,
        fetch_every_s=1.0,
    )
    if stopped.is_set():
        return ProposalAttempt(None, reason="stopped")
    results = follower.snapshot()[0]
    if not heard or not results:
        return ProposalAttempt(None, reason="results missing")
    try:
        proposal, spent = propose(bus, space, message, results)
    except SolverUnavailable as error:
        return ProposalAttempt(None, reason=str(error))
    return ProposalAttempt(proposal, spent)
