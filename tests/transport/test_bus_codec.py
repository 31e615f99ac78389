"""Hostile payloads from the bus: refused with the reason, counted, never raised as
anything but BadMessage."""

from __future__ import annotations

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import UavResult, UavState
from fleet.transport.bus_codec import (
    DROPPED,
    MAX_PAYLOAD_BYTES,
    BadMessage,
    DropReason,
    decode,
    encode,
)

SPACE = KeySpace()

DEPTH = 100_000
HOSTILE = {
    "nested arrays": (b"[" * DEPTH + b"]" * DEPTH, DropReason.INVALID),
    "nested objects": (b'{"a":' * DEPTH + b"1" + b"}" * DEPTH, DropReason.TOO_DEEP),
    "nested in a skipped field": (
        b'{"uav": 999, "x": ' + b"[" * DEPTH + b"]" * DEPTH + b"}",
        DropReason.TOO_DEEP,
    ),
    "huge": (b'{"text": "' + b"x" * MAX_PAYLOAD_BYTES + b'"}', DropReason.TOO_LARGE),
    "not json": (b"\xff\x00garbage", DropReason.INVALID),
    "wrong schema": (b'{"uav": "seventy-four"}', DropReason.INVALID),
    "wrong key": (encode(UavResult(5, 112, (1.0,))), DropReason.WRONG_KEY),
}


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_payload_is_refused_and_counted(name: str) -> None:
    payload, reason = HOSTILE[name]
    key = SPACE.state(999) if reason != DropReason.WRONG_KEY else SPACE.mission_result(5, 74)
    kind: type = UavState if reason != DropReason.WRONG_KEY else UavResult
    before = DROPPED.counts().get(str(reason), 0)
    with pytest.raises(BadMessage, match=key) as raised:
        decode(payload, kind, key)
    assert raised.value.reason == reason
    assert DROPPED.counts()[str(reason)] == before + 1


def test_a_good_message_passes() -> None:
    result = UavResult(5, 74, (1.0, None))
    assert decode(encode(result), UavResult, SPACE.mission_result(5, 74)) == result
