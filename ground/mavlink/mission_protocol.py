"""The MAVLink mission protocol, as a vehicle speaks it: pure state machines.

Upload (ground station to vehicle): MISSION_COUNT, then the vehicle asks for each item
with MISSION_REQUEST_INT and the station answers MISSION_ITEM_INT; after the last item
the vehicle answers MISSION_ACK. `MissionUpload` is one such transfer: it says what to
send next (`Request`, `Refuse`) and, once every item came and each is one the fleet can
fly, `Complete` with the targets; the gateway acks that only once the fleet took the
mission. An item the fleet cannot fly ends the transfer at once with the MISSION_ACK
error of its kind and a reason that names it. A silent station is asked again, then the
transfer is cancelled: nothing here waits for ever.

Download: `download_items` is the mission the UAV is flying, item by item.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from fleet.mission.messages import MAX_TARGETS, Target

#: How long the vehicle waits for an item before asking again, and how often it asks.
ITEM_TIMEOUT_S = 1.5
ITEM_RETRIES = 4

#: Frames whose x/y are latitude/longitude. The fleet has no home position: an altitude
#: relative to home is read as relative to 0 m, the same number (docs/mavlink.md).
_GLOBAL_FRAMES = frozenset(
    {
        mavlink2.MAV_FRAME_GLOBAL,
        mavlink2.MAV_FRAME_GLOBAL_INT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    }
)


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM(_INT), latitude and longitude in degrees whichever it was."""

    seq: int
    frame: int
    command: int
    lat: float
    lon: float
    alt: float
    mission_type: int = mavlink2.MAV_MISSION_TYPE_MISSION


def item_from_message(message: object) -> MissionItem:
    """A MISSION_ITEM_INT (x, y in 1e-7 degrees) or a MISSION_ITEM (in degrees)."""
    # Dividing (not multiplying by 1e-7) gives back the decimal degrees typed in.
    scale = 1e7 if isinstance(message, mavlink2.MAVLink_mission_item_int_message) else 1.0
    return MissionItem(
        seq=int(getattr(message, "seq")),  # noqa: B009 - pymavlink messages are untyped
        frame=int(getattr(message, "frame")),  # noqa: B009
        command=int(getattr(message, "command")),  # noqa: B009
        lat=float(getattr(message, "x")) / scale,  # noqa: B009
        lon=float(getattr(message, "y")) / scale,  # noqa: B009
        alt=float(getattr(message, "z")),  # noqa: B009
        mission_type=int(getattr(message, "mission_type", 0)),
    )


@dataclass(frozen=True)
class Refusal:
    """A MISSION_ACK error (`MAV_MISSION_RESULT`) and why, for STATUSTEXT."""

    result: int
    reason: str


def _command_name(command: int) -> str:
    entry = mavlink2.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"command {command}"


def item_problem(item: MissionItem) -> Refusal | None:
    """Why the fleet cannot fly `item`, None if it can: a NAV_WAYPOINT at a place."""
    where = f"mission item {item.seq}"
    if item.command != mavlink2.MAV_CMD_NAV_WAYPOINT:
        return Refusal(
            mavlink2.MAV_MISSION_UNSUPPORTED,
            f"{where}: {_command_name(item.command)} unsupported, only NAV_WAYPOINT",
        )
    if item.frame not in _GLOBAL_FRAMES:
        return Refusal(
            mavlink2.MAV_MISSION_UNSUPPORTED_FRAME, f"{where}: frame {item.frame} unsupported"
        )
    if not (math.isfinite(item.lat) and -90.0 <= item.lat <= 90.0):
        return Refusal(mavlink2.MAV_MISSION_INVALID_PARAM5_X, f"{where}: bad latitude")
    if not (math.isfinite(item.lon) and -180.0 <= item.lon <= 180.0):
        return Refusal(mavlink2.MAV_MISSION_INVALID_PARAM6_Y, f"{where}: bad longitude")
    if not math.isfinite(item.alt):
        return Refusal(mavlink2.MAV_MISSION_INVALID_PARAM7, f"{where}: bad altitude")
    return None


def count_problem(count: int, mission_type: int) -> Refusal | None:
    """Why a MISSION_COUNT is refused before any item is asked for, None if it is not."""
    if mission_type != mavlink2.MAV_MISSION_TYPE_MISSION:
        return Refusal(mavlink2.MAV_MISSION_UNSUPPORTED, "only missions, no fences or rally points")
    if count == 0:
        return Refusal(
            mavlink2.MAV_MISSION_DENIED, "an empty mission: nothing to assign (RTL aborts)"
        )
    if count > MAX_TARGETS:
        return Refusal(
            mavlink2.MAV_MISSION_NO_SPACE, f"{count} items: a mission holds {MAX_TARGETS} at most"
        )
    return None


# ---- what an upload says to do next ---------------------------------------------------------
@dataclass(frozen=True)
class Request:
    """Send MISSION_REQUEST_INT for item `seq`."""

    seq: int


@dataclass(frozen=True)
class Refuse:
    """Send MISSION_ACK with this error; the transfer is over."""

    refusal: Refusal


@dataclass(frozen=True)
class Complete:
    """Every item came and each can be flown: these are the targets."""

    targets: tuple[Target, ...]


Step = Request | Refuse | Complete


@dataclass
class MissionUpload:
    """One upload from one ground station (`partner`: its system and component ids)."""

    partner: tuple[int, int]
    count: int
    started_at: float
    items: list[MissionItem] = field(default_factory=list)
    asked_at: float = 0.0
    asks: int = 0

    @classmethod
    def start(
        cls, partner: tuple[int, int], count: int, mission_type: int, now: float
    ) -> tuple[MissionUpload | None, Step]:
        """A new transfer and its first step; (None, Refuse) if the count is refused."""
        problem = count_problem(count, mission_type)
        if problem is not None:
            return None, Refuse(problem)
        upload = cls(partner, count, now)
        return upload, upload._ask(now)

    @property
    def expected(self) -> int:
        return len(self.items)

    def _ask(self, now: float) -> Request:
        self.asked_at = now
        self.asks += 1
        return Request(self.expected)

    def on_item(self, item: MissionItem, now: float) -> Step | None:
        """The station sent an item. None: nothing to send (a duplicate of an earlier one)."""
        if item.mission_type != mavlink2.MAV_MISSION_TYPE_MISSION or item.seq < self.expected:
            return None
        if item.seq > self.expected:
            # Out of order: ask again for the one wanted (the protocol's recovery).
            return self._ask(now)
        problem = item_problem(item)
        if problem is not None:
            return Refuse(problem)
        self.items.append(item)
        self.asks = 0
        if self.expected == self.count:
            return Complete(tuple(Target(i.lat, i.lon, i.alt) for i in self.items))
        return self._ask(now)

    def on_tick(self, now: float) -> Step | None:
        """Ask again after a silence; give up after `ITEM_RETRIES` asks."""
        if now - self.asked_at < ITEM_TIMEOUT_S:
            return None
        if self.asks > ITEM_RETRIES:
            return Refuse(
                Refusal(
                    mavlink2.MAV_MISSION_OPERATION_CANCELLED,
                    f"upload cancelled: no mission item {self.expected} after {self.asks} requests",
                )
            )
        return self._ask(now)


def download_item(
    targets: tuple[Target, ...], seq: int, current: int | None, partner: tuple[int, int]
) -> mavlink2.MAVLink_mission_item_int_message | None:
    """Item `seq` of the mission the UAV is flying (its target `current`), None if it has
    no such item."""
    if not 0 <= seq < len(targets):
        return None
    target = targets[seq]
    return mavlink2.MAVLink_mission_item_int_message(
        partner[0],
        partner[1],
        seq,
        mavlink2.MAV_FRAME_GLOBAL_INT,
        mavlink2.MAV_CMD_NAV_WAYPOINT,
        int(seq == current),
        1,
        0.0,
        0.0,
        0.0,
        math.nan,
        round(target.lat * 1e7),
        round(target.lon * 1e7),
        target.alt,
        mavlink2.MAV_MISSION_TYPE_MISSION,
    )
