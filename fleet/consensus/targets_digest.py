"""The digest of a mission's targets: how a UAV proves it holds *the* mission sent.

A mission id alone does not: two grounds (or a ground that could not see the fleet's
missions) may send two different missions under one id, and a UAV holding the first
would seem to acknowledge the second. Each UAV reports the digest of the MissionTargets
it holds in its state (`MissionProgress.targets_digest`); the ground compares it with
the digest of what it sent (`ground.mission_ack`).

The digest is SHA-256 over a canonical MessagePack form: each struct a map of its
fields in declaration order, *leaving out every field at its default*. So the same
message gives the same digest on every machine whatever JSON spacing it travelled
with, and an onboard whose messages gained a field (new fields come last, with a
default) still agrees with a ground that does not know the field, while it is unused.
"""

from __future__ import annotations

from functools import lru_cache

import msgspec

from fleet.consensus.digest import sha256
from fleet.mission.messages import MissionTargets

__all__ = ["struct_digest", "targets_digest"]

_encoder = msgspec.msgpack.Encoder()


#: A field as the canonical form needs it: name, encoded name, default (or NODEFAULT).
_Field = tuple[str, str, object]


# msgspec.structs.fields resolves the type hints at each call: once per struct type.
@lru_cache(maxsize=64)
def _fields_of(kind: type[msgspec.Struct]) -> tuple[_Field, ...]:
    return tuple(
        (
            field.name,
            field.encode_name,
            field.default
            if field.default_factory is msgspec.NODEFAULT
            else field.default_factory(),
        )
        for field in msgspec.structs.fields(kind)
    )


def _canonical(value: object) -> object:
    if isinstance(value, msgspec.Struct):
        canonical: dict[str, object] = {}
        for name, encode_name, default in _fields_of(type(value)):
            item = getattr(value, name)
            if default is msgspec.NODEFAULT or item != default:
                canonical[encode_name] = _canonical(item)
        return canonical
    if isinstance(value, tuple | list):
        return [_canonical(item) for item in value]
    return value


def struct_digest(value: msgspec.Struct) -> str:
    """The hex SHA-256 (64 characters) of `value`'s canonical form (above)."""
    return sha256(_encoder.encode(_canonical(value))).hexdigest()


@lru_cache(maxsize=8)
def _digest(targets: MissionTargets) -> str:
    return struct_digest(targets)


class _Latest:
    """The last mission digested, by identity: a UAV reports its state several times a
    second with the one MissionTargets it holds, and hashing the struct for the LRU
    cache's key costs about 3x encoding the whole state (bench/bench_targets_digest.py)."""

    entry: tuple[MissionTargets, str] | None = None


def targets_digest(targets: MissionTargets) -> str:
    """The hex SHA-256 of `targets` (64 characters)."""
    latest = _Latest.entry  # one read: another thread may replace it meanwhile
    if latest is not None and latest[0] is targets:
        return latest[1]
    digest = _digest(targets)
    _Latest.entry = (targets, digest)
    return digest
