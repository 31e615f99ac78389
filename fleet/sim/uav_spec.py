"""One simulated aircraft as a scenario describes it: Piccolo ID, start state, plan.

Kept apart from `fleet.sim.scenario` (which reads TOML files) so that the simulated
autopilot, and anything else that flies a `UavSpec`, does not depend on file reading.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.piccolo.waypoint import Waypoint
from fleet.sim.flight_plan import closed_chain, racetrack

__all__ = ["UavSpec"]


@dataclass(frozen=True, slots=True)
class UavSpec:
    """One aircraft of a scenario: its Piccolo ID, start state and flight plan."""

    piccolo_id: int
    lat: float  #: degrees
    lon: float  #: degrees
    alt: float  #: metres
    heading: float  #: degrees true, [0, 360)
    airspeed: float  #: m/s
    plan: tuple[tuple[float, float, float], ...] | None = None  #: (lat, lon, alt) points

    def plan_points(self) -> list[tuple[float, float, float]]:
        """The plan's points, or the default racetrack ahead of the start."""
        if self.plan is not None:
            return list(self.plan)
        return racetrack(self.lat, self.lon, self.alt, self.heading)

    def waypoints(self) -> list[Waypoint]:
        """The flight plan as waypoints 0, 1, ..., the last linked back to 0."""
        return closed_chain(self.plan_points())
