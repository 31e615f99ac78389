"""Warnings and errors kept in view: which status messages the status box pins.

Status messages carry a kind (`fleet.mission.status_kind.StatusKind`), and the kind
its severity. Info messages stream past; a UAV's warnings and errors are *pinned*,
shown apart from the stream, until one of these happens:

* a later message of the same UAV says the condition cleared (`CLEARED_BY`):
  - a `link_back` message clears that UAV's `link_lost` alert (and nothing else does);
  - a `module_set` message (the answer to an OPM command) clears an `opm_refused` alert;
  - a message about a later mission (its `mission` above the mission the alert was
    about) clears every other alert of that UAV: a new mission supersedes what went
    wrong in the old one. An alert about no mission is about the mission the UAV last
    named before it (or none, and then any mission named later clears it);
* the UAV raised `PER_UAV` newer warnings or errors (the oldest goes);
* the box holds at most `MAX_PINNED` alerts (the oldest goes).

A UAV that leaves keeps its alerts: its last error is what the operator needs most.
Pure: no I/O, no clock; the caller stamps each message.
"""

from __future__ import annotations

from dataclasses import dataclass

from fleet.mission.phase import Severity
from fleet.mission.status_kind import StatusKind

#: Alerts kept per UAV.
PER_UAV = 3
#: Alerts kept in all.
MAX_PINNED = 12

#: The alert kinds a later message of one kind clears (whatever the missions).
CLEARED_BY: dict[StatusKind, StatusKind] = {
    StatusKind.LINK_LOST: StatusKind.LINK_BACK,
    StatusKind.OPM_REFUSED: StatusKind.MODULE_SET,
}
#: Alert kinds only their own clearing message clears: a lost link outlives missions.
_ONLY_CLEARED_BY_KIND = frozenset({StatusKind.LINK_LOST})


@dataclass(frozen=True)
class StatusRecord:
    """One status message as the ground received it."""

    time: float  #: wall clock, seconds since the epoch
    uav: int
    text: str
    kind: StatusKind = StatusKind.INFO
    mission: int | None = None  #: the mission the message is about, if any

    @property
    def severity(self) -> Severity:
        return self.kind.severity

    @property
    def alert(self) -> bool:
        return self.severity is not Severity.INFO


@dataclass(frozen=True)
class _Pinned:
    record: StatusRecord
    mission: int | None  #: the mission the alert is about (named, or the UAV's last)


def _clears(pinned: _Pinned, later: StatusRecord) -> bool:
    kind = pinned.record.kind
    if CLEARED_BY.get(kind) is later.kind:
        return True
    if kind in _ONLY_CLEARED_BY_KIND or later.mission is None:
        return False
    return pinned.mission is None or later.mission > pinned.mission


class Alerts:
    """The pinned warnings and errors of every UAV (see the module's rules)."""

    def __init__(self, per_uav: int = PER_UAV, max_pinned: int = MAX_PINNED) -> None:
        self._per_uav = per_uav
        self._max = max_pinned
        self._pinned: list[_Pinned] = []  #: oldest first
        self._last_mission: dict[int, int] = {}  #: the latest mission each UAV named

    def add(self, record: StatusRecord) -> None:
        named = record.mission
        self._pinned = [
            p for p in self._pinned if p.record.uav != record.uav or not _clears(p, record)
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
