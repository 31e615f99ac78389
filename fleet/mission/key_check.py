"""Does a message fit the key it arrived on? The bus's first line of defence.

Anyone who can publish on the bus can put anything under any key, so a message is
believed only as far as its key vouches for it: a result or assignment of UAV n only on
UAV n's key, a mission's messages only on that mission's keys, and every id in range
(Piccolo IDs 1-65520, mission ids u32). `check_key` raises `WrongKey` with the reason;
the transport drops and counts the message (`fleet.transport.bus_codec`). Where a key
holds its ids is its pattern in the key registry (`fleet.mission.key_registry`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from fleet.errors import FleetError
from fleet.mission.key_space import KeySpace, space_of
from fleet.mission.messages import (
    MISSION_MANAGER,
    AssignmentHeader,
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    PlanProposal,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.piccolo.stream_packet import MAX_PICCOLO_ID, MIN_PICCOLO_ID
from fleet.piccolo.waypoint import MAX_INDEX, Waypoint

MAX_MISSION_ID = 0xFFFF_FFFF
#: Target indices are u16 on the planning protocol.
MAX_TARGET_INDEX = 0xFFFF


class WrongKey(FleetError, ValueError):
    """A message that its key does not vouch for (or a key that is not the fleet's)."""


@dataclass(frozen=True)
class KeyIds:
    """The ids a fleet key names; None where it names none."""

    uav: int | None
    mission: int | None
    index: int | None  #: a waypoint's index in `{prefix}/uav/{id}/waypoint/{index}`


def _number(text: str, low: int, high: int, what: str, key: str) -> int:
    # Digits only: int() would also take "+7", " 7" and "7_0".
    if not text.isascii() or not text.isdigit() or len(text) > 10:
        raise WrongKey(f"{key}: {what} {text!r} is not a decimal number")
    value = int(text)
    if not low <= value <= high:
        raise WrongKey(f"{key}: {what} {value} outside {low}-{high}")
    return value


# Every message a process decodes has its key parsed, and most keys recur (a UAV's
# telemetry, state, link; a mission's keys across its epochs and re-fetches): the ids of
# the last PARSED_KEYS keys are kept. Bounded, so a flood of distinct keys costs a parse
# each and no memory; a refused key is never kept (WrongKey is raised, not cached).
PARSED_KEYS = 1024


#: Piccolo IDs in decimal already found valid (in keys, and as an assignment's pair
#: keys): a team's IDs recur in every key and report. At most PARSED_KEYS (emptied when
#: full).
_PICCOLO_IDS: dict[str, int] = {}


def _piccolo_id(text: str, key: str) -> int:
    value = _PICCOLO_IDS.get(text)
    if value is None:
        value = _number(text, MIN_PICCOLO_ID, MAX_PICCOLO_ID, "Piccolo ID", key)
        if len(_PICCOLO_IDS) >= PARSED_KEYS:
            _PICCOLO_IDS.clear()
        _PICCOLO_IDS[text] = value
    return value


def parse_key(key: str, space: KeySpace | None = None) -> KeyIds:
    """The ids in a `{prefix}/uav/{id}/...` or `{prefix}/mission/{m}/...` key of `space`;
    WrongKey if bad.

    Without `space`, the key's own prefix (its first chunk) is taken: a key that arrives
    is parsed this way, and every subscription of a process is under its own prefix, so
    it is the process's. A first chunk that is not a key prefix is a wrong key.
    """
    if space is None:
        space = space_of(key)
        if space is None:
            raise WrongKey(f"{key}: not a fleet message key")
    return _parse_key(key, space)


@functools.lru_cache(maxsize=PARSED_KEYS)
def _parse_key(key: str, space: KeySpace) -> KeyIds:
    parsed = space.parse(key)
    if parsed is not None:  # a registered key: its ids are where its pattern says
        uav, mission, index = parsed.uav, parsed.mission, parsed.index
    else:  # a key no registered pattern names: its ids by their place in its tree
        uav, mission, index = _ids_by_place(key, space)
    # Checked in key order (a mission id comes before the member's Piccolo ID).
    mission_id = None if mission is None else _number(mission, 0, MAX_MISSION_ID, "mission id", key)
    uav_id = None if uav is None else _piccolo_id(uav, key)
    index_value = None if index is None else _number(index, 0, MAX_INDEX, "waypoint index", key)
    return KeyIds(uav_id, mission_id, index_value)


def _ids_by_place(key: str, space: KeySpace) -> tuple[str | None, str | None, str | None]:
    """(UAV, mission, None) as `{prefix}/uav/{id}/...` and `{prefix}/mission/{m}/x/{id}`
    place them; WrongKey for a key under neither tree."""
    parts = key.split("/")
    if len(parts) < 4 or not space.owns(key):
        raise WrongKey(f"{key}: not a fleet message key")
    if parts[1] == "uav":
        return parts[2], None, None
    if parts[1] == "mission":
        return (parts[4] if len(parts) == 5 else None), parts[2], None
    raise WrongKey(f"{key}: not a fleet message key")


def uav_of(key: str, space: KeySpace | None = None) -> int:
    """The Piccolo ID a `{prefix}/uav/{id}/...` or `.../{id}` key names; WrongKey if none."""
    uav = parse_key(key, space).uav
    if uav is None:
        raise WrongKey(f"{key}: names no UAV")
    return uav


def _same(key: str, what: str, in_key: int | None, in_message: int) -> None:
    if in_key is not None and in_key != in_message:
        raise WrongKey(f"{key}: carries {what} {in_message}, not the key's {in_key}")


def _team(key: str, team: tuple[int, ...]) -> None:
    if not team or (min(team) >= MIN_PICCOLO_ID and max(team) <= MAX_PICCOLO_ID):
        return  # the common case, in C; else the first member out of range is named
    for uav in team:
        if not MIN_PICCOLO_ID <= uav <= MAX_PICCOLO_ID:
            raise WrongKey(f"{key}: team member {uav} is not a Piccolo ID")


def check_key(key: str, message: object) -> None:
    """Raise WrongKey unless `message` may travel on `key` (under the key's own prefix:
    see `parse_key`)."""
    ids = parse_key(key)
    # One lookup by type instead of a chain of isinstance checks (every message a
    # process decodes comes through here); a subclass finds its base's checks.
    check = _CHECKS.get(type(message))
    if check is None:
        check = next((c for kind, c in _CHECKS.items() if isinstance(message, kind)), None)
    if check is not None:
        check(key, ids, message)


def _check_result(key: str, ids: KeyIds, message: UavResult | TargetOutcome) -> None:
    _same(key, "UAV", ids.uav, message.uav)
    _same(key, "mission", ids.mission, message.mission)


def _check_header(key: str, ids: KeyIds, message: AssignmentHeader) -> None:
    _same(key, "UAV", ids.uav, message.uav)
    _same(key, "mission", ids.mission, message.mission)
    _team(key, message.released)


def _check_report(key: str, ids: KeyIds, message: AssignmentReport) -> None:
    _same(key, "UAV", ids.uav, message.uav)
    _same(key, "mission", ids.mission, message.mission)
    _team(key, message.team)
    _team(key, message.released)
    indices = [*message.pairs.values(), *message.unassigned]
    if message.target is not None:
        indices.append(message.target)
    if indices and not (min(indices) >= 0 and max(indices) <= MAX_TARGET_INDEX):
        raise WrongKey(f"{key}: a target index outside 0-{MAX_TARGET_INDEX}")
    _team(key, tuple(message.pairs))


def _check_targets(key: str, ids: KeyIds, message: MissionTargets) -> None:
    _same(key, "mission", ids.mission, message.mission)
    _team(key, message.team)


def _check_abort(key: str, ids: KeyIds, message: MissionAbort) -> None:
    _same(key, "mission", ids.mission, message.mission)


def _check_state(key: str, ids: KeyIds, message: UavState) -> None:
    _same(key, "UAV", ids.uav, message.uav)
    if message.mission is None:
        return
    progress = message.mission
    if not 0 <= progress.mission <= MAX_MISSION_ID:
        raise WrongKey(f"{key}: mission id {progress.mission} is not a u32")
    for own in (progress.result, progress.assignment):
        if own is not None:
            _same(key, "UAV", message.uav, own.uav)
            _same(key, "mission", progress.mission, own.mission)


def _check_waypoint(key: str, ids: KeyIds, message: Waypoint) -> None:
    if ids.index is not None:
        _same(key, "waypoint index", ids.index, message.index)


def _check_proposal(key: str, ids: KeyIds, message: PlanProposal) -> None:
    # A UAV proposes on its own key only, as itself (its signature binds it to the key);
    # the ground's key carries the ground's proposals only.
    _same(key, "mission", ids.mission, message.mission)
    _same(key, "proposer", MISSION_MANAGER if ids.uav is None else ids.uav, message.proposer)


_CHECKS: dict[type, Callable[[str, KeyIds, Any], None]] = {
    UavResult: _check_result,
    TargetOutcome: _check_result,
    AssignmentHeader: _check_header,
    AssignmentReport: _check_report,
    MissionTargets: _check_targets,
    MissionAbort: _check_abort,
    UavState: _check_state,
    Waypoint: _check_waypoint,
    PlanProposal: _check_proposal,
}
