"""msgspec compiles a type (a decoder, a JSON schema) under one lock
(`bus_codec.TYPE_INFO_LOCK`): two threads compiling the same Struct types at once
crashed `fleet up` (bench/msgspec_compile_race.py)."""

from __future__ import annotations

import threading
from typing import Any

import msgspec
import pytest

from fleet.mission import schemas
from fleet.recording import channels
from fleet.transport import bus_codec


def held_by_another_thread() -> bool:
    """Whether some thread holds the lock (tried from a thread of its own)."""
    held: list[bool] = []

    def probe() -> None:
        got = bus_codec.TYPE_INFO_LOCK.acquire(blocking=False)
        if got:
            bus_codec.TYPE_INFO_LOCK.release()
        held.append(not got)

    thread = threading.Thread(target=probe)
    thread.start()
    thread.join()
    return held[0]


class Fresh(msgspec.Struct):
    x: int


def test_a_decoder_is_compiled_under_the_lock(monkeypatch: pytest.MonkeyPatch) -> None:
    real, seen = msgspec.json.Decoder, list[bool]()

    def spy(kind: Any) -> msgspec.json.Decoder[Any]:
        seen.append(held_by_another_thread())
        return real(kind)

    monkeypatch.setattr(msgspec.json, "Decoder", spy)
    assert bus_codec.decode_json(b'{"x": 1}', Fresh, "k") == Fresh(1)
    assert seen == [True]


def test_a_recording_channels_schema_is_compiled_under_the_lock(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real, seen = schemas.render, list[bool]()

    def spy(name: str) -> str:
        seen.append(held_by_another_thread())
        return real(name)

    monkeypatch.setattr(schemas, "render", spy)
    name = next(iter(schemas.MESSAGES))
    assert channels._schema_bytes.__wrapped__(name)
    assert seen == [True]
