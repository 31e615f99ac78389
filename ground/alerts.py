"""Warnings and errors kept in view: which status messages the status box pins.

Status messages carry a severity (`fleet.mission.phase.Severity`). Info messages
stream past; a UAV's warnings and errors are *pinned*, shown apart from the stream,
until one of these happens:

* a later message of the same UAV says the condition cleared:
  - `autopilot link back ...` clears that UAV's `autopilot link lost` alert;
  - `module on|off ...` (the answer to an OPM command) clears an `error: OPM ...` alert;
  - a message naming a later mission (`mission N ...`, N above the mission the alert
    was about) clears every other alert of that UAV: a new mission supersedes what went
    wrong in the old one. An alert that names no mission is about the mission the UAV
    last named before it (or none, and then any mission named later clears it);
* the UAV raised `PER_UAV` newer warnings or errors (the oldest goes);
* the box holds at most `MAX_PINNED` alerts (the oldest goes).

A UAV that leaves keeps its alerts: its last error is what the operator needs most.
Pure: no I/O, no clock; the caller stamps each message.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from fleet.mission.phase import Severity

#: Alerts kept per UAV.
PER_UAV = 3
#: Alerts kept in all.
MAX_PINNED = 12

_MISSION = re.compile(r"\bmission (\d+)\b")
_LINK_LOST = "autopilot link lost"
_LINK_BACK = "autopilot link back"


@dataclass(frozen=True)
class StatusRecord:
    """One status message as the ground received it."""

    time: float  #: wall clock, seconds since the epoch
    uav: int
    text: str
    severity: Severity = Severity.INFO

    @property
    def alert(self) -> bool:
        return self.severity is not Severity.INFO


def mission_named(text: str) -> int | None:
    """The first mission id a status text names (`mission 3: ...`), if any."""
    match = _MISSION.search(text)
    return int(match.group(1)) if match else None


@dataclass(frozen=True)
class _Pinned:
    record: StatusRecord
    mission: int | None  #: the mission the alert is about (named, or the UAV's last)


def _clears(pinned: _Pinned, later: StatusRecord, later_mission: int | None) -> bool:
    text = pinned.record.text
    if _LINK_LOST in text:
        return later.text.startswith(_LINK_BACK)
    if text.startswith("error: OPM") and later.text.startswith("module "):
        return True
    if later_mission is None:
        return False
    return pinned.mission is None or later_mission > pinned.mission


class Alerts:
    """The pinned warnings and errors of every UAV (see the module's rules)."""

    def __init__(self, per_uav: int = PER_UAV, max_pinned: int = MAX_PINNED) -> None:
        self._per_uav = per_uav
        self._max = max_pinned
        self._pinned: list[_Pinned] = []  #: oldest first
        self._last_mission: dict[int, int] = {}  #: the latest mission each UAV named

    def add(self, record: StatusRecord) -> None:
        named = mission_named(record.text)
        self._pinned = [
            p for p in self._pinned if p.record.uav != record.uav or not _clears(p, record, named)
        ]
        if record.alert:
            about = named if named is not None else self._last_mission.get(record.uav)
            self._pinned.append(_Pinned(record, about))
            own = [p for p in self._pinned if p.record.uav == record.uav]
            for gone in own[: max(0, len(own) - self._per_uav)]:
                self._pinned.remove(gone)
            del self._pinned[: max(0, len(self._pinned) - self._max)]
        if named is not None:
            self._last_mission[record.uav] = max(named, self._last_mission.get(record.uav, named))

    def pinned(self) -> list[StatusRecord]:
        """The pinned alerts, oldest first."""
        return [p.record for p in self._pinned]
