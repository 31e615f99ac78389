"""Piccolo IDs (16-bit) as MAVLink system ids (8-bit).

IDs 1-254 are their own system id unless `--sysid PICCOLO=SYS` says otherwise; any
other ID needs a `--sysid`. Two UAVs on one system id would mix their missions and
commands, so every collision is refused, at start with a clear error, and at run time
(a UAV appears whose own id another UAV was mapped to) by not showing the newcomer.
System id 255 is left to ground stations, 0 is the broadcast address.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable

from fleet.errors import FleetError
from fleet.transport.cli import piccolo_id

MIN_SYSID = 1
MAX_SYSID = 254


class SysIdError(FleetError, ValueError):
    """A system-id mapping that cannot be used."""


def sysid_pair(text: str) -> tuple[int, int]:
    """`300=12` -> (300, 12), for argparse."""
    piccolo, sep, system = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"{text!r} is not PICCOLO=SYSID")
    try:
        sysid = int(system)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{system!r} is not a whole number") from None
    if not MIN_SYSID <= sysid <= MAX_SYSID:
        raise argparse.ArgumentTypeError(
            f"system id {sysid} out of range {MIN_SYSID}-{MAX_SYSID} (255 is for ground stations)"
        )
    return piccolo_id(piccolo.strip()), sysid


class SysIdMap:
    """The mapping both ways; built from the `--sysid` pairs (SysIdError on a collision)."""

    def __init__(self, pairs: Iterable[tuple[int, int]] = ()) -> None:
        self._explicit: dict[int, int] = {}
        owner: dict[int, int] = {}
        for piccolo, sysid in pairs:
            if piccolo in self._explicit and self._explicit[piccolo] != sysid:
                raise SysIdError(
                    f"UAV {piccolo} mapped twice (system ids {self._explicit[piccolo]} and {sysid})"
                )
            if sysid in owner and owner[sysid] != piccolo:
                raise SysIdError(
                    f"system id {sysid} given to both UAV {owner[sysid]} and UAV {piccolo}"
                )
            self._explicit[piccolo] = sysid
            owner[sysid] = piccolo
        self._owner = owner

    def sysid_of(self, piccolo: int) -> int | None:
        """`piccolo`'s system id; None if it has none or its own id is taken by another."""
        if piccolo in self._explicit:
            return self._explicit[piccolo]
        if MIN_SYSID <= piccolo <= MAX_SYSID and piccolo not in self._owner:
            return piccolo
        return None

    def why_hidden(self, piccolo: int) -> str:
        """Why `piccolo` has no system id (for the operator)."""
        if piccolo in self._owner:
            return (
                f"UAV {piccolo} is not shown: its own system id {piccolo} is given to UAV "
                f"{self._owner[piccolo]} by --sysid; map it with --sysid {piccolo}=SYS"
            )
        return (
            f"UAV {piccolo} is not shown: Piccolo IDs above {MAX_SYSID} need "
            f"--sysid {piccolo}=SYS ({MIN_SYSID}-{MAX_SYSID})"
        )

    def piccolo_of(self, sysid: int) -> int | None:
        """The UAV shown as `sysid`, None if none can be."""
        if sysid in self._owner:
            return self._owner[sysid]
        if MIN_SYSID <= sysid <= MAX_SYSID and sysid not in self._explicit:
            return sysid
        return None
