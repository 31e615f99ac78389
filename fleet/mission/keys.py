"""Every Zenoh key expression of the fleet, in one place.

Layout (all under the prefix `fleet`):

    fleet/uav/{id}/alive               liveliness token: the UAV process is up
    fleet/uav/{id}/telemetry           Telemetry (latest TELEMETRY_HI_RES)
    fleet/uav/{id}/track               Track (the waypoint the autopilot tracks)
    fleet/uav/{id}/waypoint/{index}    Waypoint (as echoed by the autopilot)
    fleet/uav/{id}/status              StatusText (thesis PAYLOAD_STATUS)
    fleet/uav/{id}/link                LinkHealth
    fleet/uav/{id}/state               queryable: UavState
    fleet/uav/{id}/opm                 OpmCommand, ground -> UAV
    fleet/uav/{id}/cmd/waypoint        queryable: Waypoint in, CommandResult out
    fleet/uav/{id}/cmd/track           queryable: Track in, CommandResult out
    fleet/mission/{m}/targets          MissionTargets, ground -> team (queryable too)
    fleet/mission/{m}/result/{id}      UavResult (queryable too: late fetch)
    fleet/mission/{m}/assignment/{id}  AssignmentReport (republished at each re-plan epoch)
    fleet/mission/{m}/replan/{id}      AssignmentReport of a re-plan (epoch > 0) only: what
                                       teammates subscribe to (docs/lifecycle.md)
    fleet/mission/{m}/outcome/{id}     TargetOutcome: reached, failed or link_lost
    fleet/mission/{m}/abort            MissionAbort, ground -> team

{id} is the Piccolo ID in decimal; {m} the mission id in decimal.

The prefix is one setting for every tool: $FLEET_KEY_PREFIX (one key chunk, default
`fleet`), read when this module is first imported, or `--key-prefix` on a command line
(`use_prefix`, which every command calls before it opens a session). A replay
(`fleet replay`) publishes under another prefix (`replay` by default) so it is never
mistaken for the live fleet; point any tool at it with `--key-prefix replay`. Code
reads the prefix when it uses a key (`keys.telemetry(7)`, `keys.ALL_ALIVE`), never
copies it at import.
"""

from __future__ import annotations

import os
import re

PREFIX_ENV = "FLEET_KEY_PREFIX"
DEFAULT_PREFIX = "fleet"
_CHUNK = re.compile(r"^[A-Za-z0-9_-]+$")


def checked_prefix(text: str) -> str:
    """`text` if it is one key chunk (letters, digits, _ and -); ValueError says why not."""
    if not _CHUNK.match(text):
        raise ValueError(
            f"key prefix {text!r}: expected one key chunk of letters, digits, '_' or '-'"
        )
    return text


PREFIX = checked_prefix(os.environ.get(PREFIX_ENV, DEFAULT_PREFIX))

# The wildcards over every UAV or mission; `use_prefix` re-derives them.
ALL_ALIVE = ALL_TELEMETRY = ALL_TRACK = ALL_WAYPOINTS = ALL_STATUS = ALL_STATE = ""
ALL_MISSION_KEYS = ALL_MISSION_TARGETS = ALL_MISSION_RESULTS = ALL_MISSION_ASSIGNMENTS = ""
ALL_MISSION_ABORTS = ALL_MISSION_OUTCOMES = ALL_MISSION_REPLANS = ""


def use_prefix(prefix: str) -> None:
    """Make `prefix` the key prefix of this process (ValueError if it is not one chunk)."""
    global PREFIX, ALL_ALIVE, ALL_TELEMETRY, ALL_TRACK, ALL_WAYPOINTS, ALL_STATUS, ALL_STATE
    global ALL_MISSION_KEYS, ALL_MISSION_TARGETS, ALL_MISSION_RESULTS, ALL_MISSION_ASSIGNMENTS
    global ALL_MISSION_ABORTS, ALL_MISSION_OUTCOMES, ALL_MISSION_REPLANS
    PREFIX = checked_prefix(prefix)
    ALL_ALIVE = f"{PREFIX}/uav/*/alive"
    ALL_TELEMETRY = f"{PREFIX}/uav/*/telemetry"
    ALL_TRACK = f"{PREFIX}/uav/*/track"
    ALL_WAYPOINTS = f"{PREFIX}/uav/*/waypoint/*"
    ALL_STATUS = f"{PREFIX}/uav/*/status"
    ALL_STATE = f"{PREFIX}/uav/*/state"
    ALL_MISSION_KEYS = f"{PREFIX}/mission/**"
    ALL_MISSION_TARGETS = f"{PREFIX}/mission/*/targets"
    ALL_MISSION_RESULTS = f"{PREFIX}/mission/*/result/*"
    ALL_MISSION_ASSIGNMENTS = f"{PREFIX}/mission/*/assignment/*"
    ALL_MISSION_REPLANS = f"{PREFIX}/mission/*/replan/*"
    ALL_MISSION_ABORTS = f"{PREFIX}/mission/*/abort"
    ALL_MISSION_OUTCOMES = f"{PREFIX}/mission/*/outcome/*"


use_prefix(PREFIX)


def uav(uav_id: int, leaf: str) -> str:
    return f"{PREFIX}/uav/{uav_id}/{leaf}"


def alive(uav_id: int) -> str:
    return uav(uav_id, "alive")


def telemetry(uav_id: int) -> str:
    return uav(uav_id, "telemetry")


def track(uav_id: int) -> str:
    return uav(uav_id, "track")


def waypoint(uav_id: int, index: int) -> str:
    return uav(uav_id, f"waypoint/{index}")


def status(uav_id: int) -> str:
    return uav(uav_id, "status")


def link(uav_id: int) -> str:
    return uav(uav_id, "link")


def state(uav_id: int) -> str:
    return uav(uav_id, "state")


def opm(uav_id: int) -> str:
    return uav(uav_id, "opm")


def command(uav_id: int, name: str) -> str:
    return uav(uav_id, f"cmd/{name}")


def mission_targets(mission: int) -> str:
    return f"{PREFIX}/mission/{mission}/targets"


def mission_result(mission: int, uav_id: int) -> str:
    return f"{PREFIX}/mission/{mission}/result/{uav_id}"


def mission_results(mission: int) -> str:
    return f"{PREFIX}/mission/{mission}/result/*"


def mission_assignment(mission: int, uav_id: int) -> str:
    return f"{PREFIX}/mission/{mission}/assignment/{uav_id}"


def mission_assignments(mission: int) -> str:
    return f"{PREFIX}/mission/{mission}/assignment/*"


def mission_replan(mission: int, uav_id: int) -> str:
    return f"{PREFIX}/mission/{mission}/replan/{uav_id}"


def mission_outcome(mission: int, uav_id: int) -> str:
    return f"{PREFIX}/mission/{mission}/outcome/{uav_id}"


def mission_outcomes(mission: int) -> str:
    return f"{PREFIX}/mission/{mission}/outcome/*"


def mission_abort(mission: int) -> str:
    return f"{PREFIX}/mission/{mission}/abort"


def uav_id_of(key: str) -> int:
    """The Piccolo ID in a `fleet/uav/{id}/...` or `fleet/mission/{m}/.../{id}` key."""
    parts = key.split("/")
    if len(parts) >= 3 and parts[1] == "uav":
        return int(parts[2])
    return int(parts[-1])


def mission_of(key: str) -> int:
    """The mission id in a `fleet/mission/{m}/...` key."""
    return int(key.split("/")[2])
