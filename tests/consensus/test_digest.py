"""The built-in SHA-256 gives hashlib's digests, and the onboard never loads OpenSSL."""

from __future__ import annotations

import hashlib
import random
import subprocess
import sys

import pytest

from fleet.consensus.digest import sha256


def test_same_digests_as_hashlib() -> None:
    rng = random.Random(14)
    for size in (0, 1, 55, 56, 63, 64, 65, 1000, 20_000):
        data = rng.randbytes(size)
        assert sha256(data).hexdigest() == hashlib.sha256(data).hexdigest()
        split = sha256(data[: size // 2])
        split.update(data[size // 2 :])
        assert split.digest() == hashlib.sha256(data).digest()


@pytest.mark.e2e
def test_onboard_process_loads_neither_hashlib_nor_openssl() -> None:
    code = (
        "import sys, onboard.process, fleet.consensus.replan;"
        "print(sorted(m for m in ('hashlib', '_hashlib', '_ssl') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert out.stdout.strip() == "[]"
