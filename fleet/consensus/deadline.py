"""How long a UAV waits for its teammates' results: a deadline that follows the team.

The deadline is the time after which a UAV commits with the results it holds. Too short
and the first UAVs commit without the slower ones (a thinner assignment, and at worst
the teammates disagree); too long and a dead teammate that Zenoh has not yet declared
gone holds the team up. A fixed 10 s was too short for 50 UAVs on one small machine
(their solves shared two cores) and needlessly long for two.

The deadline covers the slowest teammate's solve (at most its planning budget: past it
the model stops starting LPs and the Dubins time answers) plus the exchange of results,
which grows with the team (every UAV publishes one, every UAV reads them all), with a
safety factor of 2; never under `MIN_DEADLINE_S`. Pure.
"""

from __future__ import annotations

import math

#: The onboard module's default planning budget (s): `onboard --budget`.
PLAN_BUDGET_S = 2.0
#: The deadline never drops below this (s): the thesis's 10 s.
MIN_DEADLINE_S = 10.0
#: Seconds of result exchange per team member (the consensus step measured at N=50,
#: 0.5-1.4 s on a 2-core machine, with margin; docs/benchmarks.md).
EXCHANGE_PER_UAV_S = 0.1
#: Room for a loaded machine, a retried fetch and a late sample.
SAFETY = 2.0
#: The longest deadline computed (s): the ground's bound on `--deadline` too.
MAX_DEADLINE_S = 3600.0


def consensus_deadline(team_size: int, plan_budget_s: float = PLAN_BUDGET_S) -> float:
    """The deadline (s) for a team of `team_size` whose members plan within `plan_budget_s`."""
    if team_size < 1:
        raise ValueError(f"a team has at least one UAV, got {team_size}")
    if not math.isfinite(plan_budget_s) or plan_budget_s < 0:
        raise ValueError(f"planning budget must be finite and >= 0, got {plan_budget_s}")
    wanted = SAFETY * (plan_budget_s + EXCHANGE_PER_UAV_S * team_size)
    return round(min(MAX_DEADLINE_S, max(MIN_DEADLINE_S, wanted)), 1)
