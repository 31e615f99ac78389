"""A mission's acknowledgement, verified by content: which team UAVs hold the mission
the ground sent, and which hold *another* mission under the same id (a collision).

A UAV acknowledges a mission by reporting it in its state. The id alone proves little:
a ground that could not see the fleet's missions (or a rival ground) may send a mission
under an id the UAVs already hold with other targets, and the UAVs keep the first
(a mission id not above theirs is no news). So each UAV's state also carries the digest
of the targets it holds (`MissionProgress.targets_digest`), compared here with the
digest of the targets sent. A UAV that does not report a digest (an older onboard) is
believed on the id, as before.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from fleet.consensus.targets_digest import targets_digest
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from fleet.transport.bus import Bus
from ground.fleet_view import query_states
from ground.mission_control import MissionError


@dataclass
class Acknowledgement:
    """What the team's states say about a mission sent."""

    #: Team UAVs holding the mission sent (or a later one).
    got: set[int] = field(default_factory=set)
    #: Team UAVs holding other targets under the mission's id.
    collided: set[int] = field(default_factory=set)

    def collision(self, sent: MissionTargets) -> MissionCollision | None:
        """The error to report if any team UAV holds another mission under the id."""
        if not self.collided:
            return None
        return MissionCollision(
            f"mission {sent.mission}: UAV {', '.join(map(str, sorted(self.collided)))} "
            f"holds another mission under id {sent.mission} (its targets differ from those "
            "sent): not delivered"
        )


class MissionCollision(MissionError):
    """A team UAV holds a different mission under the id of the one sent."""


def acknowledgement(
    bus: Bus, space: KeySpace, sent: MissionTargets, timeout_s: float
) -> Acknowledgement:
    """One look at the team's states."""
    digest = targets_digest(sent)
    team = set(sent.team)
    seen = Acknowledgement()
    for uav, state in query_states(bus, space, timeout_s).items():
        progress = state.mission
        if uav not in team or progress is None or progress.mission < sent.mission:
            continue
        held = progress.targets_digest
        if progress.mission == sent.mission and held is not None and held != digest:
            seen.collided.add(uav)
        else:
            seen.got.add(uav)
    return seen


def wait_acknowledged(
    bus: Bus, space: KeySpace, sent: MissionTargets, timeout_s: float
) -> Acknowledgement:
    """Poll the team's states until each UAV holds the mission sent, or holds another
    under its id (which will not change: that UAV ignores the one sent), or time is up.
    What one poll heard counts even if a later poll misses that UAV's state."""
    team = set(sent.team)
    deadline = time.monotonic() + timeout_s
    heard = Acknowledgement()
    while True:
        remaining = deadline - time.monotonic()
        seen = acknowledgement(bus, space, sent, max(0.1, min(1.0, remaining)))
        heard.collided |= seen.collided
        heard.got = (heard.got | seen.got) - heard.collided
        if team <= heard.got | heard.collided or remaining <= 0:
            return heard
        time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
