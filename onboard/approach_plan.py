"""Asking the planner for this UAV's approach times to a mission's targets.

The request is posed in a local frame at the aircraft (its GPS fix, its velocity); the
answer is taken only if it is the one to the request of the current mission.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from fleet.geo.mercator import MercatorProjection
from fleet.geo.wind import CALM_AIR, Wind, airspeed
from fleet.mission.messages import MissionTargets
from fleet.mission.no_fly import local_zones
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock
from onboard.planner.planner_worker import PlanRequest, PlanResult

#: The share of a mission's deadline the approach model may use (see `budget`).
PLAN_SHARE_OF_DEADLINE = 0.5


class Planner(Protocol):
    """The RunMILP / IsMILPRunning contract (thesis 2.8): see onboard.planner.planner_worker."""

    def run(self, request: PlanRequest) -> bool: ...
    def result(self) -> PlanResult | None: ...


@dataclass
class ApproachPlan:
    planner: Planner
    planning_budget_s: float = 2.0
    _request: PlanRequest | None = None  #: the plan asked for the current mission
    #: Where the current request was posed from (lat, lon): its local frame's origin.
    origin: tuple[float, float] | None = None

    def start(
        self,
        targets: MissionTargets,
        gps: GpsBlock,
        wind: Wind = CALM_AIR,
        true_airspeed: float | None = None,
        budget_s: float | None = None,
    ) -> bool:
        """Ask for the approach times from `gps` to `targets` in `wind` (the smoothed
        estimate, onboard.planner.wind_estimate) at `true_airspeed` (the autopilot's, from
        its air data; None: the GPS velocity less the wind), within `budget_s` (None: the
        mission's `budget`); False if the planner refused.

        The air data's airspeed, where there is one: the GPS velocity less a smoothed
        wind moves with every gust the estimate has not followed (the windy scenario:
        19.9 to 23.4 m/s for aircraft all flying 22), and an upwind time is that error
        times the airspeed over the ground speed (x 2.2 at 22 m/s in 10 m/s)."""
        projection = MercatorProjection(gps.lat, gps.lon)
        request = PlanRequest(
            position=(0.0, 0.0),
            velocity=(gps.vel_east, gps.vel_north),
            targets=tuple(projection.to_xy(t.lat, t.lon) for t in targets.targets),
            budget_s=self.budget(targets) if budget_s is None else budget_s,
            cruise_speed=(
                true_airspeed
                if true_airspeed is not None
                else airspeed((gps.vel_east, gps.vel_north), wind)
            ),
            wind=wind,
            zones=local_zones(projection, targets.zones),
        )
        # The planner drops a run still under way for an older mission: its answer would
        # be that mission's approach times.
        if not self.planner.run(request):
            return False
        self._request = request
        self.origin = (gps.lat, gps.lon)
        return True

    def forget(self) -> None:
        """A new mission: no answer to an older request is ever taken."""
        self._request = None

    def budget(self, targets: MissionTargets) -> float:
        """The planning budget for this mission: the module's own, or half the mission's
        deadline if that is longer. The other half is for the exchange of results: the
        ground lengthens the deadline for a large team (fleet.consensus.deadline), and
        the approach model gets that time too, instead of answering by the fallback."""
        return max(self.planning_budget_s, PLAN_SHARE_OF_DEADLINE * targets.deadline_s)

    def take(self) -> PlanResult | None:
        """The planner's answer, if one came and it is to the current request."""
        result = self.planner.result()
        if result is None or result.request is not self._request:
            return None  # the answer to a superseded mission: never used for this one
        return result


def plan_status(plan: PlanResult, mission: int | str) -> tuple[StatusKind, str]:
    """The status message that reports `plan`: its kind and text."""
    fallbacks = sum(plan.fallback)
    text = f"mission {mission}: approach times in {plan.solve_seconds:.2f} s"
    text += f" ({plan.cpu_seconds:.3f} s of CPU)"
    if fallbacks:
        budget = plan.request.budget_s
        text += f"; {fallbacks} by the Dubins fallback (budget {budget:g} s)"
    if plan.routes:
        around = sum(1 for route in plan.routes if route is not None and route.detours)
        unreachable = [str(i) for i, route in enumerate(plan.routes) if route is None]
        text += f"; {around} routed around no-fly zones"
        if unreachable:
            text += f"; no route around the no-fly zones to target(s) {', '.join(unreachable)}"
    wind = plan.request.wind
    if wind:
        # As an operator reads a wind: where it blows from, degrees true.
        origin = math.degrees(math.atan2(-wind.east, -wind.north)) % 360.0
        text += f"; in a wind from {origin:03.0f} deg at {wind.speed:.1f} m/s"
    if plan.error:
        return StatusKind.SOLVER_DEGRADED, f"warning: {text}; solver error: {plan.error}"
    return StatusKind.APPROACH_TIMES, text
