"""The kinds of status message a UAV sends, and the one rule giving each its severity.

Receivers act on a status message's kind (and the mission and target it names), never
on its text: the text is for people. The binary payload link carries the text alone;
its edge (`fleet.payload.bodies.decode_status`) maps it to one of the generic kinds
`INFO`, `WARNING` or `ERROR` by its `error:` / `warning:` prefix, the only place a
prefix is read.
"""

from __future__ import annotations

from enum import StrEnum

from fleet.mission.phase import Severity


class StatusKind(StrEnum):
    """What a status message reports. Values are the strings on the bus."""

    # The generic kinds: a text whose kind is not known (the binary payload link's).
    INFO = "info"
    WARNING = "warning"
    ERROR = "error"
    # The autopilot link (onboard.link_watch).
    LINK_LOST = "link_lost"
    LINK_BACK = "link_back"
    # The ground's OPM command (onboard.core).
    OPM_REFUSED = "opm_refused"
    MODULE_SET = "module_set"  #: the OPM command applied: module on or off, the state rate
    # A mission's part (onboard.mission_participation).
    MISSION_REFUSED = "mission_refused"
    ARRIVED_ABORTED = "arrived_aborted"  #: the mission's abort came before its targets
    SITTING_OUT = "sitting_out"  #: the module is off: an all-None result, no flight
    NOT_TAKING_PART = "not_taking_part"  #: no GPS, a lost link, or the planner refused
    COMPUTING = "computing"
    APPROACH_TIMES = "approach_times"
    SOLVER_DEGRADED = "solver_degraded"  #: approach times computed, with a solver error
    DEADLINE_PASSED = "deadline_passed"  #: decided without some teammates' results
    ADOPTED = "adopted"
    TARGET_CHOSEN = "target_chosen"
    NO_TARGET = "no_target"
    TEAMMATE_DROPPED = "teammate_dropped"
    TEAMMATE_LOST = "teammate_lost"
    REPLANNED = "replanned"
    MISSION_CHANGED = "mission_changed"  #: targets added or removed in flight
    ORPHAN_REFUSED = "orphan_refused"  #: handed a target after its part was over
    CANNOT_FLY = "cannot_fly"
    ABORTED = "aborted"
    # Flying the target (onboard.target_flight).
    FLYING_TO_TARGET = "flying_to_target"
    REACHED = "reached"
    NOT_REACHED = "not_reached"  #: the autopilot left the target route short of it
    TARGET_GIVEN_UP = "target_given_up"  #: the ground commanded the autopilot directly
    STALE_TARGET_LEFT = "stale_target_left"  #: still tracking a target no longer held
    # The mission's no-fly zones (onboard.zone_watch).
    ZONE_INCURSION = "zone_incursion"  #: the aircraft is inside a no-fly zone
    ZONE_LEFT = "zone_left"  #: and out of it again

    @property
    def severity(self) -> Severity:
        """How much a message of this kind matters to the operator: the one rule."""
        return _SEVERITY.get(self, Severity.INFO)


_SEVERITY = {
    StatusKind.WARNING: Severity.WARNING,
    StatusKind.ERROR: Severity.ERROR,
    StatusKind.LINK_LOST: Severity.ERROR,
    StatusKind.OPM_REFUSED: Severity.ERROR,
    StatusKind.MISSION_REFUSED: Severity.ERROR,
    StatusKind.CANNOT_FLY: Severity.ERROR,
    StatusKind.NOT_TAKING_PART: Severity.WARNING,
    StatusKind.SOLVER_DEGRADED: Severity.WARNING,
    StatusKind.DEADLINE_PASSED: Severity.WARNING,
    StatusKind.ORPHAN_REFUSED: Severity.WARNING,
    StatusKind.NOT_REACHED: Severity.WARNING,
    StatusKind.TARGET_GIVEN_UP: Severity.WARNING,
    StatusKind.STALE_TARGET_LEFT: Severity.WARNING,
    StatusKind.ZONE_INCURSION: Severity.ERROR,
}
