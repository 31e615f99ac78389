"""Tests of the shared decoder shape and sync hunt (fleet.piccolo.decoder)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.payload.protocol import PlanningDecoder
from fleet.payload.resync import PlanningStreamDecoder
from fleet.piccolo.autopilot_packet import AutopilotPacketDecoder
from fleet.piccolo.decoder import Decoder, Reject, ResyncDecoder
from fleet.piccolo.stream_packet import StreamDecoder


class LengthPrefixed(ResyncDecoder[bytes]):
    """A toy framing: sync AB, a length byte, that many bytes; a length over 8 is bad."""

    SYNC = b"AB"
    REASONS = ("too_long",)

    def _frame(self, buffer: bytearray, start: int) -> tuple[bytes, int] | Reject | None:
        if len(buffer) - start < 3:
            return None
        size = buffer[start + 2]
        if size > 8:
            return Reject("too_long")
        stop = start + 3 + size
        if len(buffer) < stop:
            return None
        return bytes(buffer[start + 3 : stop]), stop


def frame(body: bytes) -> bytes:
    return b"AB" + bytes((len(body),)) + body


@pytest.mark.parametrize(
    "decoder",
    [StreamDecoder(), AutopilotPacketDecoder(), PlanningStreamDecoder(), PlanningDecoder()],
    ids=type,
)
def test_every_stream_decoder_has_the_one_shape(decoder: Decoder[object]) -> None:
    assert isinstance(decoder, Decoder)
    assert decoder.feed(b"\x00\x01\x02", now=5.0) == []
    assert decoder.drops["skipped_bytes"] == 3


def test_garbage_before_a_sync_is_skipped_and_counted() -> None:
    decoder = LengthPrefixed()
    assert decoder.feed(b"xyz" + frame(b"hi") + b"q" + frame(b"")) == [b"hi", b""]
    assert decoder.drops == {"too_long": 0, "skipped_bytes": 4}
    assert decoder.packets == 2


def test_a_rejected_candidate_costs_one_byte_and_the_hunt_resumes() -> None:
    # A false sync whose "length" swallows a real frame: the real one is still found.
    decoder = LengthPrefixed()
    assert decoder.feed(b"AB\xff" + frame(b"ok")) == [b"ok"]
    assert decoder.drops == {"too_long": 1, "skipped_bytes": 3}


def test_a_trailing_half_sync_is_kept_for_the_next_chunk() -> None:
    decoder = LengthPrefixed()
    assert decoder.feed(b"zzA") == []
    assert decoder.buffered == 1
    assert decoder.feed(b"B\x01!") == [b"!"]
    assert decoder.drops["skipped_bytes"] == 2
    assert decoder.buffered == 0


def test_an_incomplete_frame_waits_for_its_bytes() -> None:
    decoder = LengthPrefixed()
    wire = frame(b"12345678")
    assert decoder.feed(wire[:5]) == []
    assert decoder.buffered == 5
    assert decoder.feed(wire[5:]) == [b"12345678"]


@given(st.lists(st.binary(max_size=8), max_size=6), st.binary(max_size=40), st.integers(1, 9))
def test_every_byte_is_delivered_skipped_or_held(
    bodies: list[bytes], noise: bytes, chunk: int
) -> None:
    data = noise + b"".join(frame(b) for b in bodies)
    decoder = LengthPrefixed()
    delivered = 0
    for start in range(0, len(data), chunk):
        delivered += sum(3 + len(b) for b in decoder.feed(data[start : start + chunk]))
    assert delivered + decoder.drops["skipped_bytes"] + decoder.buffered == len(data)


@given(st.binary(max_size=12), st.lists(st.binary(max_size=8), min_size=1, max_size=4))
def test_a_read_that_is_one_whole_frame_decodes_as_the_hunt_does(
    before: bytes, bodies: list[bytes]
) -> None:
    """A chunk that makes the held bytes exactly one frame (what a live link reads) is
    taken without the hunt: the same items, drops, count and held bytes as a decoder
    fed the same bytes one at a time, whatever it held before."""
    whole, byte_by_byte = LengthPrefixed(), LengthPrefixed()
    for decoder in (whole, byte_by_byte):
        decoder.feed(before)
    for body in bodies:
        items = whole.feed(frame(body))
        expected = [i for b in frame(body) for i in byte_by_byte.feed(bytes((b,)))]
        assert items == expected
        assert whole.drops == byte_by_byte.drops
        assert whole.packets == byte_by_byte.packets
        assert whole.buffered == byte_by_byte.buffered
