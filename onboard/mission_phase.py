"""The phase of this UAV's part in its current mission, and why it is what it is.

Shared by the roles that move it: taking part in the mission (onboard.mission_participation)
and flying its target (onboard.target_flight). Every move is by the one life-cycle table
of `fleet.mission.lifecycle` (docs/lifecycle.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.mission.lifecycle import Observation, advance, holds_target
from fleet.mission.phase import Phase


@dataclass
class MissionPhase:
    phase: Phase = Phase.IDLE
    reason: str | None = None  #: why the phase is what it is, where that needs saying

    def observe(self, observation: Observation, reason: str | None = None) -> bool:
        """Move the phase by the life-cycle table; True if it changed."""
        after = advance(self.phase, observation)
        if after == self.phase:
            return False
        self.phase = after
        self.reason = reason
        return True

    def holds_target(self) -> bool:
        return holds_target(self.phase)
