"""This UAV's result in a mission: its approach times, computed and published.

The planner (onboard.approach_plan) computes them off the main loop; the result goes to
the team on its key and to the ground over the payload port. A UAV that takes no part
publishes an all-None result, so that its teammates need not wait for it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import msgspec

from fleet.consensus.mission_round import MissionRound
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.wind import CALM_AIR, Wind
from fleet.mission.key_space import KeySpace
from fleet.mission.lifecycle import Observation
from fleet.mission.messages import MissionTargets, UavResult
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock
from onboard.approach_plan import ApproachPlan, plan_status
from onboard.mission_phase import MissionPhase
from onboard.planner.planner_worker import PlanRequest
from onboard.state_report import ReportOutputs, Say

_LIMITS = AircraftLimits()


@dataclass(frozen=True, slots=True)
class FlownAir:
    """What the result says of how this UAV flies: its teammates time its legs by it
    (fleet.consensus.legs.Air)."""

    airspeed: float
    wind: Wind
    origin: tuple[float, float] | None


def flown_air(request: PlanRequest, origin: tuple[float, float] | None) -> FlownAir | None:
    """The airspeed and wind the approach times were planned at (the request's: the
    smoothed wind, the GPS velocity less it), rounded to the centimetre per second; None
    where the request has no cruise speed or a number is not finite."""
    speed = request.cruise_speed
    wind = request.wind
    if speed is None or not all(math.isfinite(v) for v in (speed, wind.east, wind.north)):
        return None
    return FlownAir(
        round(_LIMITS.clamp_airspeed(speed), 2),
        Wind(round(wind.east, 2), round(wind.north, 2)),
        origin,
    )


@dataclass
class OwnResult:
    uav_id: int
    key_space: KeySpace
    #: Where the result goes: the bus and the payload link, as the state report's.
    outputs: ReportOutputs
    plan: ApproachPlan
    life: MissionPhase
    say: Say
    #: The standing being computed (fleet.consensus.resolve): (basis, flying, reached);
    #: None while the planner computes the mission's first result, or nothing.
    standing: tuple[str, int | None, tuple[int, ...]] | None = None
    #: The bases this UAV gave (or is giving) a standing for: one each.
    stood: set[str] = field(default_factory=set)
    #: Whether this UAV will propose a plan for a mission (onboard.plan_proposer), said
    #: in its result for it; None: it proposes nothing (started without `--propose`).
    will_propose: Callable[[MissionTargets], bool] | None = None

    def start(
        self,
        mission_round: MissionRound,
        gps: GpsBlock,
        now: float,
        wind: Wind = CALM_AIR,
        true_airspeed: float | None = None,
    ) -> bool:
        """Start computing the approach times in `wind` at `true_airspeed` (None: from
        the GPS); False if the planner refused."""
        if not self.plan.start(mission_round.targets, gps, wind, true_airspeed):
            return False
        self.standing = None
        self.say(
            StatusKind.COMPUTING,
            f"mission {mission_round.mission}: computing approach times to "
            f"{len(mission_round.targets.targets)} targets",
            now,
            mission=mission_round.mission,
        )
        return True

    def start_standing(
        self,
        mission_round: MissionRound,
        basis: str,
        where: tuple[GpsBlock, Wind, float | None],
        flying: int | None,
        reached: tuple[int, ...],
    ) -> bool:
        """Start computing this UAV's standing for the re-plan of append plan `basis`:
        its approach times from `where` it is now (its GPS, wind and airspeed) to every
        target of the mission's current revision, within the module's own planning
        budget; False if the planner refused."""
        self.stood.add(basis)
        gps, wind, speed = where
        budget = self.plan.planning_budget_s
        if not self.plan.start(mission_round.current, gps, wind, speed, budget_s=budget):
            return False
        self.standing = (basis, flying, reached)
        return True

    def stand_none(self, mission_round: MissionRound, basis: str) -> None:
        """Give a standing with no time at all: this UAV takes nothing in the re-plan."""
        self.stood.add(basis)
        count = len(mission_round.current.targets)
        own = self.uav_id
        reached = tuple(sorted(t for t, uav in mission_round.reached_targets.items() if uav == own))
        self._publish_standing(mission_round, basis, (None,) * count, None, reached, None)

    def _publish_standing(
        self,
        mission_round: MissionRound,
        basis: str,
        times: tuple[float | None, ...],
        flying: int | None,
        reached: tuple[int, ...],
        air: FlownAir | None,
    ) -> None:
        # Its own count of re-plans in changed air asked for: a teammate that counts
        # fewer re-plans this epoch too (onboard.mission_participation).
        asked = mission_round.membership.asked.get(self.uav_id, 0)
        result = self._result(
            mission_round, times, air, basis=basis, flying=flying, reached=reached, asked=asked
        )
        mission_round.add_standing(result)
        self.outputs.publish(self.key_space.mission_result(result.mission, self.uav_id), result)

    def collect(self, mission_round: MissionRound | None, now: float) -> bool:
        """Publish the approach times once the planner has them; True if they were a
        standing (the re-plan may be ready)."""
        result = self.plan.take()
        if result is None or mission_round is None:
            return False
        standing, self.standing = self.standing, None
        if standing is not None:
            basis, flying, reached = standing
            times = tuple(t if math.isfinite(t) else None for t in result.times)
            air = flown_air(result.request, self.plan.origin)
            self._publish_standing(mission_round, basis, times, flying, reached, air)
            return True
        if self.life.phase != Phase.COMPUTING:
            return False
        kind, text = plan_status(result, mission_round.mission)
        self.say(kind, text, now, mission=mission_round.mission)
        # An infinite time is a target no route reaches (onboard.planner.route_plan): no answer.
        times = tuple(t if math.isfinite(t) else None for t in result.times)
        self.publish(
            mission_round,
            times,
            now,
            result.model_times,
            result.fallback_times,
            air=flown_air(result.request, self.plan.origin),
        )
        return False

    def _result(
        self,
        mission_round: MissionRound,
        times: tuple[float | None, ...],
        air: FlownAir | None,
        **fields: Any,
    ) -> UavResult:
        """This UAV's result for `mission_round`, with `fields` and the air it was timed in."""
        result = UavResult(mission=mission_round.mission, uav=self.uav_id, times=times, **fields)
        return with_air(result, air)

    def _proposes(self, targets: MissionTargets) -> bool | None:
        """What this UAV's result says of its proposing for `targets`: its teammates wait
        for no plan of a named UAV that says it will not (fleet.consensus.proposal.
        awaited_proposers). None (unsaid, the digest as before) for a mission that waits
        for no named proposer."""
        if not targets.proposers or targets.proposals_s <= 0.0:
            return None
        return self.will_propose is not None and self.will_propose(targets)

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
        air: FlownAir | None = None,
    ) -> None:
        result = self._result(
            mission_round,
            times,
            air,
            model_times=model_times,
            fallback_times=fallback_times,
            proposes=self._proposes(mission_round.targets),
        )
        mission_round.add_result(result)
        # Teammates are computing too: the first fetch waits one interval.
        mission_round.last_fetch = now
        self.life.observe(Observation.RESULT_PUBLISHED)
        self.outputs.publish(self.key_space.mission_result(result.mission, self.uav_id), result)
        self.outputs.send_ground(result)


def with_air(result: UavResult, air: FlownAir | None) -> UavResult:
    """`result` carrying the air its times were computed in (what its teammates time
    its legs with), when known."""
    if air is None:
        return result
    return msgspec.structs.replace(
        result,
        airspeed=air.airspeed,
        wind_east=air.wind.east,
        wind_north=air.wind.north,
        lat=None if air.origin is None else air.origin[0],
        lon=None if air.origin is None else air.origin[1],
    )
