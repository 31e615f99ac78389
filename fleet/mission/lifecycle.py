"""The mission life cycle of one UAV: which observation moves it from which phase to which.

One table, `TRANSITIONS`, is the whole rule; `advance` applies it. The onboard module
feeds it what it observed (an autopilot echo, a position inside the acceptance radius,
the ground's abort, ...) and shows the phase it returns, so no tool ever shows a phase
the table does not allow. `off` and `link_lost` are not in the table: they describe the
aircraft, not the mission, and outrank whatever phase the mission is in
(`onboard.core.OnboardCore.overall_phase`).

Pure: no I/O, no time.
"""

from __future__ import annotations

from enum import StrEnum

from fleet.mission.phase import Phase


class Observation(StrEnum):
    """What the module saw that may change its mission phase."""

    MISSION_STARTED = "mission_started"  #: a new mission for this UAV's team arrived
    RESULT_PUBLISHED = "result_published"  #: its own approach times are out (or declined)
    ASSIGNED_TARGET = "assigned_target"  #: the consensus (or a re-plan) gave it a target
    ASSIGNED_NONE = "assigned_none"  #: the consensus left it without a target
    TRACK_ECHOED = "track_echoed"  #: the autopilot echoed the target waypoint and track
    WITHIN_RADIUS = "within_radius"  #: telemetry put it inside the acceptance radius
    LEFT_ROUTE = "left_route"  #: the autopilot stopped tracking the target elsewhere
    OPERATOR_COMMAND = "operator_command"  #: the ground commanded the autopilot directly
    COMMAND_FAILED = "command_failed"  #: the target writes could not be confirmed
    LINK_LOST = "link_lost"  #: the autopilot link went silent while the target was held
    ABORTED = "aborted"  #: the ground aborted the mission (or this UAV's part in it)
    RELEASED = "released"  #: a re-plan took its target away (it was counted as lost)


_EVERY_PHASE = frozenset(Phase) - {Phase.OFF, Phase.LINK_LOST}
#: Phases in which the UAV holds a target it has not reached yet.
HOLDING = frozenset({Phase.COMMITTED, Phase.FLYING})

#: (observation, phase before) -> phase after. A pair that is not here changes nothing.
TRANSITIONS: dict[tuple[Observation, Phase], Phase] = {
    **{(Observation.MISSION_STARTED, p): Phase.COMPUTING for p in _EVERY_PHASE},
    (Observation.RESULT_PUBLISHED, Phase.COMPUTING): Phase.WAITING,
    (Observation.ASSIGNED_TARGET, Phase.COMPUTING): Phase.COMMITTED,
    (Observation.ASSIGNED_TARGET, Phase.WAITING): Phase.COMMITTED,
    # A re-plan hands an orphaned target to a UAV that had none, or a later epoch hands
    # a candidate that already reached its orphan another one (fleet.consensus.replan).
    (Observation.ASSIGNED_TARGET, Phase.IDLE): Phase.COMMITTED,
    (Observation.ASSIGNED_TARGET, Phase.REACHED): Phase.COMMITTED,
    (Observation.ASSIGNED_NONE, Phase.COMPUTING): Phase.IDLE,
    (Observation.ASSIGNED_NONE, Phase.WAITING): Phase.IDLE,
    (Observation.TRACK_ECHOED, Phase.COMMITTED): Phase.FLYING,
    **{(Observation.WITHIN_RADIUS, p): Phase.REACHED for p in HOLDING},
    (Observation.LEFT_ROUTE, Phase.FLYING): Phase.PREEMPTED,
    **{(Observation.OPERATOR_COMMAND, p): Phase.PREEMPTED for p in HOLDING},
    (Observation.COMMAND_FAILED, Phase.COMMITTED): Phase.FAILED,
    **{(Observation.LINK_LOST, p): Phase.FAILED for p in HOLDING},
    **{(Observation.RELEASED, p): Phase.IDLE for p in HOLDING},
    # Even after `reached`: every UAV acknowledges the abort with this phase.
    **{(Observation.ABORTED, p): Phase.ABORTED for p in _EVERY_PHASE - {Phase.ABORTED}},
}


def advance(phase: Phase, observation: Observation) -> Phase:
    """The phase after `observation` in `phase` (the same phase if it changes nothing)."""
    return TRANSITIONS.get((observation, phase), phase)


def holds_target(phase: Phase) -> bool:
    """True while the UAV still owes its target: committed to it or flying to it."""
    return phase in HOLDING
