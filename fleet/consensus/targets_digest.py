"""The digest of a mission's targets: how a UAV proves it holds *the* mission sent.

A mission id alone does not: two grounds (or a ground that could not see the fleet's
missions) may send two different missions under one id, and a UAV holding the first
would seem to acknowledge the second. Each UAV reports the digest of the MissionTargets
it holds in its state (`MissionProgress.targets_digest`); the ground compares it with
the digest of what it sent (`ground.mission_ack`).

The digest is SHA-256 over the struct's MessagePack encoding, whose field order is the
struct's: the same message gives the same digest on every machine, whatever JSON
spacing or key order it travelled with.
"""

from __future__ import annotations

from functools import lru_cache

import msgspec

from fleet.consensus.digest import sha256
from fleet.mission.messages import MissionTargets

__all__ = ["targets_digest"]

_encoder = msgspec.msgpack.Encoder()


@lru_cache(maxsize=8)
def _digest(targets: MissionTargets) -> str:
    return sha256(_encoder.encode(targets)).hexdigest()


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
