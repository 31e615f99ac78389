"""Signing as a fleet identity from a test's raw Zenoh session (`fleet.mission.signature`):
what a holder of that identity's signing key can send."""

from __future__ import annotations

import time
from pathlib import Path

from fleet.files.signers import load_signing_key, signing_key_path
from fleet.mission.signature import sign


def attachment(certs: Path, identity: str, key: str, payload: bytes) -> bytes:
    """The envelope `identity` (with its key from `certs`) puts on `payload` at `key` now."""
    signing_key = load_signing_key(signing_key_path(certs, identity))
    return sign(signing_key, identity, key, payload, time.time_ns())
