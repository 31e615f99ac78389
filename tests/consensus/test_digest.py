"""The built-in SHA-256 gives hashlib's digests (that the onboard never loads hashlib or
OpenSSL is tests/onboard/test_import_footprint.py)."""

from __future__ import annotations

import hashlib
import random

from fleet.consensus.digest import sha256


def test_same_digests_as_hashlib() -> None:
    rng = random.Random(14)
    for size in (0, 1, 55, 56, 63, 64, 65, 1000, 20_000):
        data = rng.randbytes(size)
        assert sha256(data).hexdigest() == hashlib.sha256(data).hexdigest()
        split = sha256(data[: size // 2])
        split.update(data[size // 2 :])
        assert split.digest() == hashlib.sha256(data).digest()
