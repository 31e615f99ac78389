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


# A UAV reports its state several times a second: its one mission is hashed once.
@lru_cache(maxsize=8)
def targets_digest(targets: MissionTargets) -> str:
    """The hex SHA-256 of `targets` (64 characters)."""
    return sha256(_encoder.encode(targets)).hexdigest()
