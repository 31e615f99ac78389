"""How fleet messages travel on Zenoh: msgspec JSON with a declared encoding.

JSON so that any stock Zenoh tool (`z_sub`, `z_get`) can read the key space; the JSON
Schemas in `schemas/` say what each key carries.
"""

from __future__ import annotations

from typing import Any, TypeVar

import msgspec
import zenoh

from fleet.errors import CodecError

ENCODING = zenoh.Encoding.APPLICATION_JSON

_encoder = msgspec.json.Encoder()
T = TypeVar("T")


class BadMessage(CodecError):
    """A Zenoh value that is not valid JSON for the type its key carries."""


def encode(message: Any) -> bytes:
    return _encoder.encode(message)


def decode(payload: bytes, kind: type[T], key: str) -> T:
    """Decode `payload` as `kind`; BadMessage names the key and what was wrong."""
    try:
        return msgspec.json.decode(payload, type=kind)
    except (msgspec.ValidationError, msgspec.DecodeError) as error:
        raise BadMessage(f"{key}: not a valid {kind.__name__}: {error}") from error
