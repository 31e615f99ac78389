"""Deciding a mission's assignment: the first decision, and each re-plan's.

The first decision waits for the round to be ready (every live teammate's result, or
the deadline), fetching the results still missing meanwhile; when it might not be the
team's decision (`MissionRound.must_ask`), it asks the team what it decided first and
decides ASK_GRACE_S later if no answer was adopted. A re-plan (teammates released after
the commitment) fetches the results it lacks, then re-assigns their targets. Either way
the decision is returned: flying it is the mission participation's
(onboard.mission_participation).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Protocol

from fleet.consensus.mission_round import MissionRound
from fleet.consensus.proposal import ProposalRefused
from fleet.mission.messages import AssignmentReport
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus_codec import DROPPED
from onboard.state_report import Say
from onboard.team_presence import TeamPresence

log = logging.getLogger(__name__)


class DecisionOutputs(Protocol):
    def fetch_results(self, mission: int, uavs: tuple[int, ...]) -> None: ...
    def fetch_assignments(self, mission: int) -> None: ...


@dataclass
class MissionDecision:
    uav_id: int
    outputs: DecisionOutputs
    team: TeamPresence
    say: Say

    def tick(self, mission_round: MissionRound, now: float) -> AssignmentReport | None:
        """Fetch the results still missing; the decision once the round is ready."""
        if mission_round.should_fetch(now, self.team.alive):
            mission_round.last_fetch = now
            missing = mission_round.missing(self.team.alive) - {self.uav_id}
            self.outputs.fetch_results(mission_round.mission, tuple(sorted(missing)))
        if mission_round.ready(now, self.team.alive):
            return self._decide_or_ask(mission_round, now)
        return None

    def _decide_or_ask(self, mission_round: MissionRound, now: float) -> AssignmentReport | None:
        """Decide, unless the decision might not be the team's: then ask the team what
        it decided first, and decide ASK_GRACE_S later if no answer was adopted (or at
        once, if what made it uncertain is gone: a missing result arrived)."""
        if not mission_round.must_ask(self.team.alive):
            return self._decide(mission_round, now)
        if mission_round.asked_at is None:
            mission_round.asked_at = now
            excluded = sorted(mission_round.excluded(self.team.alive))
            log.info(
                "mission %d: asking the team what it decided before deciding (%s)",
                mission_round.mission,
                f"without {', '.join(map(str, excluded))}" if excluded else "the mission came late",
            )
            self.outputs.fetch_assignments(mission_round.mission)
            return None
        if not mission_round.asking(now):
            return self._decide(mission_round, now)
        return None

    def _decide(self, mission_round: MissionRound, now: float) -> AssignmentReport:
        missing = mission_round.missing(self.team.alive)
        report = mission_round.decide(self.team.alive)
        for proposer, why in sorted(mission_round.refused_proposals.items()):
            DROPPED.add(ProposalRefused.INVALID)
            log.warning(
                "mission %d: the plan proposed by %d refused: %s",
                mission_round.mission,
                proposer,
                why,
            )
        if mission_round.proposals:
            log.info(
                "mission %d: decided with %d proposal(s): digest %s, queues %s",
                mission_round.mission,
                len(mission_round.proposals),
                report.digest,
                dict(report.queues),
            )
        if missing:
            self.say(
                StatusKind.DEADLINE_PASSED,
                f"warning: mission {mission_round.mission}: deadline passed without "
                f"{', '.join(map(str, sorted(missing)))}; assigned without them",
                now,
                mission=mission_round.mission,
            )
        return report

    def replan(self, mission_round: MissionRound, now: float) -> AssignmentReport | None:
        """Re-assign the targets of released UAVs, or fetch the results that needs."""
        missing = mission_round.replan_missing()
        if missing:
            self.outputs.fetch_results(mission_round.mission, missing)
            return None
        awaited = mission_round.awaiting
        report = mission_round.replan(now)
        if report is not None:
            self.say(
                StatusKind.REPLANNED,
                f"mission {report.mission}: re-plan epoch {report.epoch} without "
                f"{', '.join(map(str, report.released))}",
                now,
                mission=report.mission,
            )
        elif mission_round.awaiting is not None and mission_round.awaiting is not awaited:
            log.info(
                "mission %d: re-plan epoch %d: waiting for the fresh times of %s",
                mission_round.mission,
                mission_round.awaiting.epoch,
                ", ".join(map(str, mission_round.missing_standings())),
            )
        return report
