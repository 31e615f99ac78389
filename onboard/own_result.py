"""This UAV's result in a mission: its approach times, computed and published.

The planner (onboard.approach_plan) computes them off the main loop; the result goes to
the team on its key and to the ground over the payload port. A UAV that takes no part
publishes an all-None result, so that its teammates need not wait for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fleet.consensus.mission_round import MissionRound
from fleet.geo.wind import CALM_AIR, Wind
from fleet.mission.key_space import KeySpace
from fleet.mission.lifecycle import Observation
from fleet.mission.messages import UavResult
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock
from onboard.approach_plan import ApproachPlan, plan_status
from onboard.mission_phase import MissionPhase
from onboard.state_report import ReportOutputs, Say


@dataclass
class OwnResult:
    uav_id: int
    key_space: KeySpace
    #: Where the result goes: the bus and the payload link, as the state report's.
    outputs: ReportOutputs
    plan: ApproachPlan
    life: MissionPhase
    say: Say

    def start(
        self, mission_round: MissionRound, gps: GpsBlock, now: float, wind: Wind = CALM_AIR
    ) -> bool:
        """Start computing the approach times in `wind`; False if the planner refused."""
        if not self.plan.start(mission_round.targets, gps, wind):
            return False
        self.say(
            StatusKind.COMPUTING,
            f"mission {mission_round.mission}: computing approach times to "
            f"{len(mission_round.targets.targets)} targets",
            now,
            mission=mission_round.mission,
        )
        return True

    def collect(self, mission_round: MissionRound | None, now: float) -> None:
        """Publish the approach times once the planner has them."""
        result = self.plan.take()
        if result is None or mission_round is None or self.life.phase != Phase.COMPUTING:
            return
        kind, text = plan_status(result, mission_round.mission)
        self.say(kind, text, now, mission=mission_round.mission)
        # An infinite time is a target no route reaches (onboard.planner.route_plan): no answer.
        times = tuple(t if math.isfinite(t) else None for t in result.times)
        self.publish(mission_round, times, now, result.model_times, result.fallback_times)

    def publish_none(self, mission_round: MissionRound, now: float) -> None:
        """Take no part: an all-None result says so to the team."""
        self.publish(mission_round, tuple(None for _ in mission_round.targets.targets), now)

    def publish(
        self,
        mission_round: MissionRound,
        times: tuple[float | None, ...],
        now: float,
        model_times: int | None = None,
        fallback_times: int | None = None,
    ) -> None:
        result = UavResult(
            mission=mission_round.mission,
            uav=self.uav_id,
            times=times,
            model_times=model_times,
            fallback_times=fallback_times,
        )
        mission_round.add_result(result)
        # Teammates are computing too: the first fetch waits one interval.
        mission_round.last_fetch = now
        self.life.observe(Observation.RESULT_PUBLISHED)
        self.outputs.publish(self.key_space.mission_result(result.mission, self.uav_id), result)
        self.outputs.send_ground(result)
