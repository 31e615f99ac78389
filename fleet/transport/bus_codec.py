"""How fleet messages travel on Zenoh: msgspec JSON with a declared encoding.

JSON so that any stock Zenoh tool (`z_sub`, `z_get`) can read the key space; the JSON
Schemas in `schemas/` say what each key carries.

Everything decoded from the bus is hostile until proven otherwise: a payload larger
than `MAX_PAYLOAD_BYTES`, nested too deep, not valid for its type, or not vouched for by
its key (`fleet.mission.key_check`) raises `BadMessage`, and is counted in `DROPPED` by
reason, so every process can say how much it refused.
"""

from __future__ import annotations

import functools
import threading
from collections import Counter
from collections.abc import Hashable
from enum import StrEnum
from typing import Any, TypeVar, cast

import msgspec
import zenoh

from fleet.errors import CodecError
from fleet.mission.key_check import WrongKey, check_key

ENCODING = zenoh.Encoding.APPLICATION_JSON
#: Far above any fleet message (a mission of 1,000 targets is ~60 kB).
MAX_PAYLOAD_BYTES = 1 << 20

_encoder = msgspec.json.Encoder()
T = TypeVar("T")


class DropReason(StrEnum):
    TOO_LARGE = "too_large"
    TOO_DEEP = "too_deep"
    INVALID = "invalid"  #: not JSON, or not the type its key carries
    WRONG_KEY = "wrong_key"  #: its key does not vouch for it


class BadMessage(CodecError):
    """A Zenoh value that is not valid for its key; `reason` says which check failed."""

    def __init__(self, message: str, reason: DropReason) -> None:
        super().__init__(message)
        self.reason = reason


class DropCounter:
    """How many bus messages this process refused, by reason (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._counts: Counter[StrEnum] = Counter()

    def add(self, reason: StrEnum) -> None:
        """Count one refusal: a DropReason, or another layer's reason (a signature's)."""
        with self._lock:
            self._counts[reason] += 1

    def counts(self) -> dict[str, int]:
        with self._lock:
            return {str(reason): count for reason, count in self._counts.items()}

    def total(self) -> int:
        with self._lock:
            return sum(self._counts.values())


#: Every message this process refused.
DROPPED = DropCounter()


def encode(message: Any) -> bytes:
    return _encoder.encode(message)


def refuse(text: str, reason: DropReason) -> BadMessage:
    """A BadMessage, counted in DROPPED."""
    DROPPED.add(reason)
    return BadMessage(text, reason)


#: Held while msgspec compiles a type (a decoder, a JSON schema). msgspec 0.22 builds a
#: Struct class's decoding info on first use and attaches it to the class before it is
#: complete, while it runs Python to read the annotations; a second thread compiling
#: the same types meanwhile takes the incomplete info and its decoder crashes (SIGSEGV
#: in `json_decode_struct_map_inner`): `fleet up` died so at start-up, its main thread
#: decoding the first telemetry while the recorder's worker made a channel's schema
#: (`bench/msgspec_compile_race.py` reproduces it with msgspec alone).
TYPE_INFO_LOCK = threading.RLock()


@functools.cache
def _decoder(kind: Any) -> msgspec.json.Decoder[Any]:
    """One decoder per message type, made on first use (msgspec compiles it once)."""
    with TYPE_INFO_LOCK:
        return msgspec.json.Decoder(kind)


def decode_json(payload: bytes, kind: type[T], key: str) -> T:
    """`payload` as `kind` (Any for untyped JSON); BadMessage if too large, deep or invalid."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise refuse(
            f"{key}: {len(payload)} bytes, more than {MAX_PAYLOAD_BYTES}", DropReason.TOO_LARGE
        )
    name = getattr(kind, "__name__", "JSON value")
    try:
        # type[T] is hashable at run time; mypy's lru_cache stub cannot tell.
        decoded: T = _decoder(cast(Hashable, kind)).decode(payload)
        return decoded
    except (msgspec.ValidationError, msgspec.DecodeError) as error:
        raise refuse(f"{key}: not a valid {name}: {error}", DropReason.INVALID) from None
    except RecursionError:
        # msgspec recurses per nesting level, even into fields it skips.
        raise refuse(f"{key}: JSON nested too deep", DropReason.TOO_DEEP) from None


def decode(payload: bytes, kind: type[T], key: str) -> T:
    """Decode `payload` as `kind` and check its key vouches for it; BadMessage says why not."""
    message = decode_json(payload, kind, key)
    try:
        check_key(key, message)
    except WrongKey as error:
        raise refuse(str(error), DropReason.WRONG_KEY) from None
    return message


def decode_header(payload: bytes, kind: type[T], key: str) -> T | None:
    """The fields of `payload` that `kind` names (a header struct: the rest is skipped,
    not validated), if they decode and its key vouches for them; None otherwise,
    uncounted: the caller then decodes it in full (`decode`), which refuses and counts.
    """
    if len(payload) > MAX_PAYLOAD_BYTES:
        return None
    try:
        header: T = _decoder(cast(Hashable, kind)).decode(payload)
        check_key(key, header)
    except (msgspec.ValidationError, msgspec.DecodeError, RecursionError, WrongKey):
        return None
    return header
