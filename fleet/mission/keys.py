"""The process's key space, for callers that do not hold a `KeySpace` yet.

The keys themselves are declared in `fleet.mission.key_registry` and built by
`fleet.mission.key_space.KeySpace`. This module is the one place that still holds
process state: the key prefix every tool of this process uses, $FLEET_KEY_PREFIX (one
key chunk, default `fleet`) read when it is first imported, or `--key-prefix` on a
command line (`use_prefix`, which every command calls before it opens a session). A
replay (`fleet replay`) publishes under another prefix (`replay` by default) so it is
never mistaken for the live fleet; point any tool at it with `--key-prefix replay`.

Its functions (`keys.telemetry(7)`) and wildcards (`keys.ALL_ALIVE`) read the current
prefix when used, never copied at import. It is a compatibility layer: it goes once
every caller takes a `KeySpace` (`current()` is the one to hand them meanwhile).
"""

from __future__ import annotations

import os

from fleet.mission.key_registry import DEFAULT_PREFIX
from fleet.mission.key_space import KeySpace, checked_prefix

__all__ = ["DEFAULT_PREFIX", "PREFIX_ENV", "KeySpace", "checked_prefix", "current", "use_prefix"]

PREFIX_ENV = "FLEET_KEY_PREFIX"

_space = KeySpace(checked_prefix(os.environ.get(PREFIX_ENV, DEFAULT_PREFIX)))

# Declared for the type checker only: module __getattr__ reads them off the current
# KeySpace at each use, so `use_prefix` changes them all at once.
PREFIX: str
ALL_ALIVE: str
ALL_TELEMETRY: str
ALL_TRACK: str
ALL_WAYPOINTS: str
ALL_STATUS: str
ALL_STATE: str
ALL_MISSION_KEYS: str
ALL_MISSION_TARGETS: str
ALL_MISSION_RESULTS: str
ALL_MISSION_ASSIGNMENTS: str
ALL_MISSION_REPLANS: str
ALL_MISSION_ABORTS: str
ALL_MISSION_OUTCOMES: str


def __getattr__(name: str) -> str:
    if name == "PREFIX":
        return _space.prefix
    if name.startswith("ALL_"):
        value = getattr(_space, name.lower(), None)
        if isinstance(value, str):
            return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def current() -> KeySpace:
    """The key space of this process."""
    return _space


def use_prefix(prefix: str) -> None:
    """Make `prefix` the key prefix of this process (ValueError if it is not one chunk)."""
    global _space
    _space = KeySpace(prefix)


def uav(uav_id: int, leaf: str) -> str:
    return _space.uav(uav_id, leaf)


def alive(uav_id: int) -> str:
    return _space.alive(uav_id)


def telemetry(uav_id: int) -> str:
    return _space.telemetry(uav_id)


def track(uav_id: int) -> str:
    return _space.track(uav_id)


def waypoint(uav_id: int, index: int) -> str:
    return _space.waypoint(uav_id, index)


def status(uav_id: int) -> str:
    return _space.status(uav_id)


def link(uav_id: int) -> str:
    return _space.link(uav_id)


def state(uav_id: int) -> str:
    return _space.state(uav_id)


def opm(uav_id: int) -> str:
    return _space.opm(uav_id)


def command(uav_id: int, name: str) -> str:
    return _space.command(uav_id, name)


def mission_targets(mission: int) -> str:
    return _space.mission_targets(mission)


def mission_result(mission: int, uav_id: int) -> str:
    return _space.mission_result(mission, uav_id)


def mission_results(mission: int) -> str:
    return _space.mission_results(mission)


def mission_assignment(mission: int, uav_id: int) -> str:
    return _space.mission_assignment(mission, uav_id)


def mission_assignments(mission: int) -> str:
    return _space.mission_assignments(mission)


def mission_replan(mission: int, uav_id: int) -> str:
    return _space.mission_replan(mission, uav_id)


def mission_outcome(mission: int, uav_id: int) -> str:
    return _space.mission_outcome(mission, uav_id)


def mission_outcomes(mission: int) -> str:
    return _space.mission_outcomes(mission)


def mission_abort(mission: int) -> str:
    return _space.mission_abort(mission)


def uav_id_of(key: str) -> int:
    """The Piccolo ID in a `{prefix}/uav/{id}/...` or `{prefix}/mission/{m}/.../{id}` key."""
    parts = key.split("/")
    if len(parts) >= 3 and parts[1] == "uav":
        return int(parts[2])
    return int(parts[-1])


def mission_of(key: str) -> int:
    """The mission id in a `{prefix}/mission/{m}/...` key."""
    return int(key.split("/")[2])
