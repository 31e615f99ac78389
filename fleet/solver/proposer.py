"""A proposal solved from the team's results, by whichever party proposes.

The proposer (the ground, or a UAV started with `--propose`) computes exactly what
every UAV computes from the same results (the legs in each UAV's air, the results
digest: `fleet.consensus.mission_round.MissionRound`), solves the queues with PyVRP
(`fleet.solver.pyvrp_plan`) and names itself as the proposer. Every UAV verifies and
scores the proposal (`fleet.consensus.proposal`): nothing here is trusted. Pure: no I/O.
"""

from __future__ import annotations

from fleet.consensus.mission_round import MissionRound
from fleet.mission.messages import MissionTargets, PlanProposal, UavResult
from fleet.solver.pyvrp_plan import solve_queues

__all__ = ["proposal_for"]


def proposal_for(
    targets: MissionTargets, results: dict[int, UavResult], proposer: int
) -> PlanProposal:
    """The plan PyVRP solves from `results` (the team's), proposed by `proposer` (a
    Piccolo ID; the ground's is MISSION_MANAGER). SolverUnavailable without PyVRP;
    ValueError when no team UAV's result is among `results`."""
    team = [uav for uav in targets.team if uav in results]
    if not team:
        raise ValueError(f"mission {targets.mission}: no team UAV's result to solve from")
    mission_round = MissionRound(targets=targets, own_id=team[0], started=0.0)
    for uav in team:
        mission_round.add_result(results[uav])
    used = {uav: mission_round.results[uav].times for uav in sorted(mission_round.results)}
    legs = mission_round.air_legs(used)
    queues = solve_queues(used, legs, targets.objective)
    return PlanProposal(
        mission=targets.mission,
        proposer=proposer,
        digest=mission_round.results_digest(used),
        objective=targets.objective,
        queues={uav: tuple(queue) for uav, queue in sorted(queues.items())},
    )
