"""Mission management (thesis 3.1.4): send targets, abort, OPM, and a mission's status.

Sending a mission: the ground claims a mission id (`ground.mission_ids`), declares its
subscribers to the mission's results, assignments and outcomes *before* it sends
(`ground.mission_follower`), so nothing a fast UAV publishes is missed, serves the
MissionTargets by query for UAVs that join late, and then puts them on
`fleet/mission/{m}/targets`. What the ground concludes is `ground.mission_outcome`.

Re-plans: after the commitment, a UAV that drops out (liveliness gone, `failed`,
`link_lost`) is released by its teammates and its target re-planned; each re-plan is
a new *epoch* of the same mission, republished on the same assignment keys, and each
UAV publishes a TargetOutcome (`fleet/mission/{m}/outcome/{id}`) when it reaches its
target or drops out. The ground reads a target as `reached` (by whom) from those.
"""

from __future__ import annotations

import logging

from fleet.errors import FleetError
from fleet.mission.claims import reached_by
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MissionAbort,
    MissionTargets,
    OpmCommand,
)
from fleet.transport.bus import Bus
from ground.fleet_view import query_states
from ground.mission_follower import MissionFollower
from ground.mission_outcome import MissionOutcome

log = logging.getLogger(__name__)


class MissionError(FleetError, RuntimeError):
    """A mission operation that cannot go ahead (no team, no mission to abort, ...)."""


def publish_targets(bus: Bus, space: KeySpace, targets: MissionTargets) -> None:
    bus.publish(space.mission_targets(targets.mission), targets)
    log.info(
        "mission %d: %d targets sent to %s",
        targets.mission,
        len(targets.targets),
        ", ".join(map(str, targets.team)),
    )


# ---- commands ----------------------------------------------------------------------------
def send_abort(bus: Bus, space: KeySpace, mission: int, uav: int | None = None) -> MissionAbort:
    """Abort `mission` for its whole team, or for UAV `uav` alone."""
    abort = MissionAbort(mission=mission, uav=uav)
    bus.publish(space.mission_abort(mission), abort)
    log.info("mission %d: abort sent to %s", mission, "the team" if uav is None else uav)
    return abort


def send_opm(
    bus: Bus, space: KeySpace, uav: int, enabled: bool, status_rate_hz: float
) -> OpmCommand:
    command = OpmCommand(enabled=enabled, status_rate_hz=status_rate_hz)
    bus.publish(space.opm(uav), command)
    log.info("UAV %d: planning module %s", uav, "on" if enabled else "off")
    return command


# ---- a mission's status, after the fact --------------------------------------------------
def mission_targets_of(bus: Bus, space: KeySpace, mission: int, timeout_s: float) -> MissionTargets:
    """The mission's targets and team, as the UAVs (or a ground still sending) serve them:
    its latest revision served (a mission changed in flight)."""
    served = [
        targets
        for _, targets in bus.query_messages(
            space.mission_targets(mission), MissionTargets, timeout_s
        )
        if targets.mission == mission
    ]
    if not served:
        raise MissionError(f"mission {mission}: no UAV or ground answers for it")
    return max(served, key=lambda targets: targets.revision)


def mission_status(
    bus: Bus,
    space: KeySpace,
    mission: int,
    timeout_s: float,
    until_reached_s: float | None = None,
) -> MissionOutcome:
    """Mission `mission` as the fleet reports it now: results, the latest epoch's
    assignment, outcomes; with `until_reached_s`, first wait that long at most for every
    target to be reached. MissionError if nothing answers for the mission."""
    targets = mission_targets_of(bus, space, mission, timeout_s)
    outcome = MissionOutcome(
        mission=mission,
        team=targets.team,
        targets=targets.targets,
        removed=frozenset(targets.removed),
    )
    with MissionFollower(bus, space, mission) as follower:
        follower.fetch(timeout_s)
        if until_reached_s is not None:
            everything = set(range(len(targets.targets))) - outcome.removed

            def all_reached() -> bool:
                return reached_by(follower.outcomes.values()).keys() >= everything

            follower.wait_until(all_reached, until_reached_s, fetch_every_s=1.0)
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
    states = query_states(bus, space, timeout_s)
    outcome.lost = {uav for uav in targets.team if uav not in states}
    for uav, state in states.items():
        if uav in outcome.team:
            outcome.note_state(state)
    return outcome
