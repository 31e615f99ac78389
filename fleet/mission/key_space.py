"""`KeySpace(prefix)`: the fleet's keys under one prefix, built and parsed from the registry.

A value, not process state: a tool that works on two prefixes at once (a replay beside
the live fleet) holds two. `KeySpace("fleet").telemetry(7)` is `fleet/uav/7/telemetry`;
`.all_alive` is `fleet/uav/*/alive`; `.parse(key)` says which registered key a key is
and the ids in it. The prefix is one key chunk (letters, digits, `_` and `-`), so that
a replay (`replay` by default) is never mistaken for the live fleet.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from fleet.mission import key_registry as reg
from fleet.mission.key_registry import DEFAULT_PREFIX, KeySpec

_CHUNK = re.compile(r"^[A-Za-z0-9_-]+$")
#: Parsed keys kept per process: most keys recur (a UAV's telemetry, a mission's keys).
PARSED_KEYS = 1024


def checked_prefix(text: str) -> str:
    """`text` if it is one key chunk (letters, digits, _ and -); ValueError says why not."""
    if not _CHUNK.match(text):
        raise ValueError(
            f"key prefix {text!r}: expected one key chunk of letters, digits, '_' or '-'"
        )
    return text


@dataclass(frozen=True)
class ParsedKey:
    """A concrete key matched to its registered spec, with its ids as the key spells them
    (not yet checked: fleet.mission.key_check does that)."""

    spec: KeySpec
    uav: str | None
    mission: str | None
    index: str | None


@dataclass(frozen=True)
class KeySpace:
    """Every key of the fleet under `prefix`."""

    prefix: str = DEFAULT_PREFIX

    def __post_init__(self) -> None:
        checked_prefix(self.prefix)

    # --- any registered key ---

    def key(self, spec: KeySpec, **ids: int | str) -> str:
        """`spec` under this prefix, with `ids` put in and `*` for the others."""
        return f"{self.prefix}/{spec.fill(**ids)}"

    def parse(self, key: str) -> ParsedKey | None:
        """The registered key `key` is, with its ids; None if it is none under this prefix."""
        return _parse(self.prefix, key)

    def owns(self, key: str) -> bool:
        """Whether `key` is under this prefix."""
        return key.partition("/")[0] == self.prefix

    # --- whole trees ---

    @property
    def everything(self) -> str:
        return f"{self.prefix}/**"

    @property
    def all_mission_keys(self) -> str:
        return f"{self.prefix}/mission/**"

    def uav_tree(self, uav_id: int) -> str:
        """Every key of one UAV: `{prefix}/uav/{id}/**`."""
        return self.uav(uav_id, "**")

    def uav(self, uav_id: int | str, leaf: str) -> str:
        """`{prefix}/uav/{id}/{leaf}`: a key or expression below one UAV (or `*`: all)."""
        return f"{self.prefix}/uav/{uav_id}/{leaf}"

    # --- one UAV's keys ---

    def alive(self, uav_id: int) -> str:
        return self.key(reg.ALIVE, id=uav_id)

    def telemetry(self, uav_id: int) -> str:
        return self.key(reg.TELEMETRY, id=uav_id)

    def track(self, uav_id: int) -> str:
        return self.key(reg.TRACK, id=uav_id)

    def waypoint(self, uav_id: int, index: int) -> str:
        return self.key(reg.WAYPOINT, id=uav_id, index=index)

    def status(self, uav_id: int) -> str:
        return self.key(reg.STATUS, id=uav_id)

    def link(self, uav_id: int) -> str:
        return self.key(reg.LINK, id=uav_id)

    def state(self, uav_id: int) -> str:
        return self.key(reg.STATE, id=uav_id)

    def opm(self, uav_id: int) -> str:
        return self.key(reg.OPM, id=uav_id)

    def command(self, uav_id: int, name: str) -> str:
        """A command queryable of a UAV by its leaf: `waypoint` or `track`."""
        return self.uav(uav_id, f"cmd/{name}")

    # --- one mission's keys ---

    def mission_targets(self, mission: int) -> str:
        return self.key(reg.TARGETS, m=mission)

    def mission_result(self, mission: int, uav_id: int) -> str:
        return self.key(reg.RESULT, m=mission, id=uav_id)

    def mission_results(self, mission: int) -> str:
        return self.key(reg.RESULT, m=mission)

    def mission_assignment(self, mission: int, uav_id: int) -> str:
        return self.key(reg.ASSIGNMENT, m=mission, id=uav_id)

    def mission_assignments(self, mission: int) -> str:
        return self.key(reg.ASSIGNMENT, m=mission)

    def mission_replan(self, mission: int, uav_id: int) -> str:
        return self.key(reg.REPLAN, m=mission, id=uav_id)

    def mission_outcome(self, mission: int, uav_id: int) -> str:
        return self.key(reg.OUTCOME, m=mission, id=uav_id)

    def mission_outcomes(self, mission: int) -> str:
        return self.key(reg.OUTCOME, m=mission)

    def mission_abort(self, mission: int) -> str:
        return self.key(reg.ABORT, m=mission)

    def mission_proposal(self, mission: int) -> str:
        return self.key(reg.PROPOSAL, m=mission)

    def uav_proposal(self, mission: int, uav_id: int) -> str:
        """A UAV's own proposal for a mission (the ground's: `mission_proposal`)."""
        return self.key(reg.UAV_PROPOSAL, m=mission, id=uav_id)

    def mission_proposals(self, mission: int) -> str:
        """Every UAV's proposal for a mission (not the ground's)."""
        return self.key(reg.UAV_PROPOSAL, m=mission)

    # --- one UAV's keys in every mission ---

    def results_of(self, uav_id: int) -> str:
        return self.key(reg.RESULT, id=uav_id)

    def assignments_of(self, uav_id: int) -> str:
        return self.key(reg.ASSIGNMENT, id=uav_id)

    def outcomes_of(self, uav_id: int) -> str:
        return self.key(reg.OUTCOME, id=uav_id)

    # --- wildcards over every UAV or mission ---

    @property
    def all_alive(self) -> str:
        return self.key(reg.ALIVE)

    @property
    def all_telemetry(self) -> str:
        return self.key(reg.TELEMETRY)

    @property
    def all_track(self) -> str:
        return self.key(reg.TRACK)

    @property
    def all_waypoints(self) -> str:
        return self.key(reg.WAYPOINT)

    @property
    def all_status(self) -> str:
        return self.key(reg.STATUS)

    @property
    def all_state(self) -> str:
        return self.key(reg.STATE)

    def router_state(self) -> str:
        return self.key(reg.ROUTER_STATE)

    def roster(self) -> str:
        return self.key(reg.ROSTER)

    def digest(self, uav_id: int) -> str:
        return self.key(reg.DIGEST, id=uav_id)

    @property
    def all_digests(self) -> str:
        return self.key(reg.DIGEST)

    @property
    def all_mission_targets(self) -> str:
        return self.key(reg.TARGETS)

    @property
    def all_mission_results(self) -> str:
        return self.key(reg.RESULT)

    @property
    def all_mission_assignments(self) -> str:
        return self.key(reg.ASSIGNMENT)

    @property
    def all_mission_replans(self) -> str:
        return self.key(reg.REPLAN)

    @property
    def all_mission_aborts(self) -> str:
        return self.key(reg.ABORT)

    @property
    def all_mission_proposals(self) -> str:
        return self.key(reg.PROPOSAL)

    @property
    def all_uav_proposals(self) -> str:
        return self.key(reg.UAV_PROPOSAL)

    @property
    def all_mission_outcomes(self) -> str:
        return self.key(reg.OUTCOME)


def uav_id_of(key: str) -> int:
    """The Piccolo ID in a `{prefix}/uav/{id}/...` or `{prefix}/mission/{m}/.../{id}` key
    (not checked: fleet.mission.key_check does that); ValueError or IndexError if none."""
    parts = key.split("/")
    if len(parts) >= 3 and parts[1] == "uav":
        return int(parts[2])
    return int(parts[-1])


def mission_of(key: str) -> int:
    """The mission id in a `{prefix}/mission/{m}/...` key."""
    return int(key.split("/")[2])


#: The fleet's keys under the default prefix.
DEFAULT_SPACE = KeySpace()

#: Key spaces kept by `space_of`: a process sees one prefix, a few at most.
SPACES = 16


def space_of(key: str) -> KeySpace | None:
    """The KeySpace `key` is under, by its first chunk; None if that is not a key prefix."""
    return _space(key.partition("/")[0])


@functools.lru_cache(maxsize=SPACES)
def _space(prefix: str) -> KeySpace | None:
    return KeySpace(prefix) if _CHUNK.match(prefix) else None


def _placeholder(chunk: str) -> str | None:
    return chunk[1:-1] if chunk.startswith("{") else None


@functools.lru_cache(maxsize=PARSED_KEYS)
def _parse(prefix: str, key: str) -> ParsedKey | None:
    parts = key.split("/")
    if parts[0] != prefix:
        return None
    rest = parts[1:]
    for spec in reg.REGISTRY:
        chunks = spec.chunks
        if len(chunks) != len(rest):
            continue
        ids: dict[str, str] = {}
        for chunk, part in zip(chunks, rest, strict=True):
            name = _placeholder(chunk)
            if name is not None:
                ids[name] = part
            elif chunk != part:
                break
        else:
            return ParsedKey(spec, ids.get(reg.UAV_ID), ids.get(reg.MISSION_ID), ids.get(reg.INDEX))
    return None
