"""Which MCAP channel and schema each fleet key is recorded on (pure), from the key
registry (`fleet.mission.key_registry`: each key's `Recording` and `Role`).

A recording has one channel per Zenoh key (its topic is the key itself, e.g.
`fleet/uav/101/telemetry`): an MCAP message carries no key of its own, so a channel per
wildcard pattern would lose which UAV sent it. Every channel names its key-expression
pattern in its metadata (`pattern`, e.g. `fleet/uav/*/telemetry`), and its schema is
the pattern's JSON Schema, generated from the message structs
(`fleet.mission.schemas`), so it is found the same way in a checkout or installed.

Two kinds of channel are derived rather than heard on the bus:

* `{prefix}/uav/{id}/location_fix`: a `foxglove.LocationFix` made from each
  telemetry, so Foxglove's map panel shows the fleet;
* `{prefix}/uav/{id}/alive`: the UAV's liveliness token appearing or going.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from fleet.mission import key_registry, schemas
from fleet.mission.key_registry import REGISTRY, Recording, Role
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.transport import bus_codec

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"
LOCATION_FIX = "foxglove.LocationFix"
LIVELINESS = "fleet.Liveliness"
LOCATION_LEAF = "location_fix"
ALIVE_LEAF = key_registry.ALIVE.leaf
STATE_LEAF = key_registry.STATE.leaf

#: Keys under the prefix that carry commands to the fleet: recorded, never replayed.
COMMAND_PATTERNS = tuple(spec.fill() for spec in REGISTRY if spec.role is Role.COMMAND)

# Foxglove's published JSON Schema of LocationFix (the fields its map panel reads).
_LOCATION_FIX_SCHEMA: dict[str, Any] = {
    "title": LOCATION_FIX,
    "description": "A navigation satellite fix for any Global Navigation Satellite System",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "frame_id": {"type": "string"},
        "latitude": {"type": "number", "description": "Latitude in degrees"},
        "longitude": {"type": "number", "description": "Longitude in degrees"},
        "altitude": {"type": "number", "description": "Altitude in meters"},
        "position_covariance": {
            "type": "array",
            "items": {"type": "number"},
            "minItems": 9,
            "maxItems": 9,
        },
        "position_covariance_type": {
            "type": "integer",
            "oneOf": [
                {"title": "UNKNOWN", "const": 0},
                {"title": "APPROXIMATED", "const": 1},
                {"title": "DIAGONAL_KNOWN", "const": 2},
                {"title": "KNOWN", "const": 3},
            ],
        },
    },
}

_LIVELINESS_SCHEMA: dict[str, Any] = {
    "title": LIVELINESS,
    "description": "A UAV's liveliness token fleet/uav/{id}/alive appeared (true) or went",
    "type": "object",
    "properties": {"alive": {"type": "boolean"}},
    "required": ["alive"],
}


@dataclass(frozen=True)
class ChannelSpec:
    """What a recording needs to register one channel."""

    topic: str
    schema_name: str
    schema: bytes = field(repr=False)
    pattern: str

    @property
    def metadata(self) -> dict[str, str]:
        return {"pattern": self.pattern}


def matches(pattern: str, key: str) -> bool:
    """Whether a key matches a key expression with `*` (one chunk) and `**` (any chunks)."""
    return _match(pattern.split("/"), key.split("/"))


def _match(pattern: list[str], key: list[str]) -> bool:
    if not pattern:
        return not key
    head, rest = pattern[0], pattern[1:]
    if head == "**":
        return any(_match(rest, key[i:]) for i in range(len(key) + 1))
    if not key:
        return False
    return (head == "*" or head == key[0]) and _match(rest, key[1:])


def strip_prefix(key: str) -> str:
    """The key without its first chunk (the key prefix)."""
    return key.partition("/")[2]


def with_prefix(key: str, prefix: str) -> str:
    """The key moved under another prefix: `fleet/uav/1/x` -> `replay/uav/1/x`."""
    return f"{prefix}/{strip_prefix(key)}"


def is_command(key: str) -> bool:
    """Whether `key` (any prefix) carries a command to the fleet."""
    rest = strip_prefix(key)
    return any(matches(pattern, rest) for pattern in COMMAND_PATTERNS)


@cache
def _message_patterns() -> tuple[tuple[str, str, str], ...]:
    """(pattern below the prefix, schema name, schema file name) for each published key."""
    return tuple(
        (spec.fill(), spec.message.__name__, key_registry.SCHEMA_FILES[spec.message])
        for spec in REGISTRY
        if spec.recording is Recording.MESSAGE and spec.message is not None
    )


@cache
def _schema_bytes(name: str) -> bytes:
    # On the recorder's worker while other threads decode: compiled under the lock.
    with bus_codec.TYPE_INFO_LOCK:
        return schemas.render(name).encode()


def channel_for(key: str) -> ChannelSpec:
    """The channel a fleet key is recorded on; keys of no known pattern get no schema."""
    prefix, _, rest = key.partition("/")
    for pattern, schema_name, file_name in _message_patterns():
        if matches(pattern, rest):
            return ChannelSpec(key, schema_name, _schema_bytes(file_name), f"{prefix}/{pattern}")
    return ChannelSpec(key, "", b"", key)


def location_channel(prefix: str, uav: int) -> ChannelSpec:
    schema = json.dumps(_LOCATION_FIX_SCHEMA).encode()
    space = KeySpace(prefix)
    return ChannelSpec(
        space.uav(uav, LOCATION_LEAF), LOCATION_FIX, schema, space.uav("*", LOCATION_LEAF)
    )


def alive_channel(prefix: str, uav: int) -> ChannelSpec:
    schema = json.dumps(_LIVELINESS_SCHEMA).encode()
    space = KeySpace(prefix)
    return ChannelSpec(space.alive(uav), LIVELINESS, schema, space.all_alive)


def heard_channel(prefix: str, key: str) -> ChannelSpec:
    """The channel of a key heard on the bus, or of a liveliness token (`{"alive": ...}`):
    `channel_for`, but a UAV's token on its `fleet.Liveliness` channel (another token
    as it is, without a schema). `fleet foxglove` serves what it hears by this."""
    spec = channel_for(key)
    if spec.topic.endswith(f"/{ALIVE_LEAF}"):
        with contextlib.suppress(ValueError, IndexError):
            return alive_channel(prefix, uav_id_of(key))
    return spec


def is_derived(spec_schema_name: str) -> bool:
    """Channels the recorder made up (map fixes): never replayed onto the bus."""
    return spec_schema_name == LOCATION_FIX


def location_fix(telemetry: dict[str, Any], uav: int, time_ns: int) -> dict[str, Any] | None:
    """A foxglove.LocationFix from a recorded Telemetry (as JSON); None without a GPS block."""
    gps = telemetry.get("gps")
    if not isinstance(gps, dict):
        return None
    try:
        lat, lon, alt = float(gps["lat"]), float(gps["lon"]), float(gps["alt"])
    except (KeyError, TypeError, ValueError):
        return None
    return {
        "timestamp": {"sec": time_ns // 1_000_000_000, "nsec": time_ns % 1_000_000_000},
        "frame_id": f"uav{uav}",
        "latitude": lat,
        "longitude": lon,
        "altitude": alt,
        "position_covariance": [0.0] * 9,
        "position_covariance_type": 0,
    }
