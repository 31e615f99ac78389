"""The typed life cycle a UAV reports, and the severity of its status messages.

Every tool shows these values and no other: the onboard module decides them from what
it observed (an autopilot echo, a position inside the acceptance radius, telemetry
age), never from what it merely asked for.
"""

from __future__ import annotations

from enum import StrEnum


class Phase(StrEnum):
    """Where a UAV stands. Values are the strings on the bus and in `--json` output."""

    IDLE = "idle"  #: no mission, or the mission left it without a target
    COMPUTING = "computing"  #: solving its approach times
    WAITING = "waiting"  #: result published, waiting for the teammates' results
    COMMITTED = "committed"  #: assignment fixed; target waypoint not yet echoed by the autopilot
    FLYING = "flying"  #: the autopilot echoed the target waypoint and is tracking it
    REACHED = "reached"  #: telemetry put the aircraft inside the acceptance radius
    PREEMPTED = "preempted"  #: the autopilot left the target route before reaching it
    ABORTED = "aborted"  #: the ground aborted the mission; course resumed
    FAILED = "failed"  #: the UAV could not fly its target (reason given)
    LINK_LOST = "link_lost"  #: no telemetry from the autopilot for longer than the limit
    OFF = "off"  #: the onboard planning module is turned off


#: Phases in which a UAV holds no live claim on its target any more.
FINAL_PHASES = frozenset({Phase.REACHED, Phase.PREEMPTED, Phase.ABORTED, Phase.FAILED})


class Severity(StrEnum):
    """How much a status message matters to the operator (`StatusKind.severity`)."""

    INFO = "info"
    WARNING = "warning"
    ERROR = "error"
