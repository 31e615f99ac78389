"""SHA-256 from CPython's built-in module, without `hashlib`.

`hashlib` loads OpenSSL's libcrypto (`_hashlib`): about 3.5 MB resident in every onboard
process that only ever hashes a few kilobytes per mission (fifty onboards on
one box). CPython's own SHA-256 (`_sha256` up to 3.11, `_sha2` from 3.12) gives the
same digests; `hashlib` is the fallback where neither is built.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Protocol, cast

__all__ = ["Hash", "sha256"]


class Hash(Protocol):
    """The part of a hashlib hash object the project uses."""

    def update(self, data: bytes, /) -> None: ...

    def digest(self) -> bytes: ...

    def hexdigest(self) -> str: ...


def _builtin_sha256() -> Callable[[bytes], Hash]:
    for name in ("_sha2", "_sha256", "hashlib"):  # 3.12+, up to 3.11, the fallback
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        return cast("Callable[[bytes], Hash]", module.sha256)
    raise ImportError("no SHA-256 implementation in this Python")


#: `sha256(data)`: a hash object with `update`, `digest` and `hexdigest`, like hashlib's.
sha256: Callable[[bytes], Hash] = _builtin_sha256()
