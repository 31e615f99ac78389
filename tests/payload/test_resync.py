"""Tests of resynchronisation on the payload stream (fleet.payload.resync)."""

from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.mission.messages import (
    BROADCAST,
    MISSION_MANAGER,
    MissionAbort,
    StatusText,
)
from fleet.payload.bodies import (
    PlanningMessage,
)
from fleet.payload.framing import (
    HEADER_SIZE,
    MAX_PACKET_SIZE,
    PAYLOAD_OPM,
    PAYLOAD_STATUS,
    PAYLOAD_UAV,
    SYNC,
    encode_packet,
)
from fleet.payload.protocol import (
    Envelope,
    PlanningDecoder,
    encode_message,
)
from fleet.payload.resync import PlanningStreamDecoder
from tests.payload.planning_samples import (
    ABORT_7,
    STATUS_OK,
    envelopes,
    messages,
    wire_of,
)

# ---------------------------------------------------------------- resynchronisation


def test_false_sync_with_bad_body_costs_one_byte() -> None:
    # A false OPM header whose 9-byte body overlaps the real packet: enabled = 0xFF.
    decoder = PlanningDecoder()
    assert decoder.feed(b"\xb5\x09\x00\x00" + ABORT_7, now=0.0) == [
        Envelope(MISSION_MANAGER, BROADCAST, MissionAbort(7))
    ]
    drops = decoder.drops
    assert (drops["bad_body"], drops["skipped_bytes"]) == (1, 4)


def test_bad_type_and_bad_size_are_skipped() -> None:
    bad_type = bytes([SYNC, 0, 7, 0, 0, 0, 0, 0])
    bad_size = bytes([SYNC, 3, PAYLOAD_OPM, 0, 0, 0, 0, 0])
    short_uav = bytes([SYNC, 3, PAYLOAD_UAV, 9, 0, 0, 0, 0, 1, 2, 3])
    decoder = PlanningStreamDecoder()
    packets = decoder.feed(bad_type + bad_size + short_uav + STATUS_OK)
    assert [p.body for p in packets] == [b"OK"]
    drops = decoder.drops
    assert (drops["bad_type"], drops["bad_size"], drops["bad_body"]) == (1, 2, 0)
    assert drops["skipped_bytes"] == len(bad_type + bad_size + short_uav)


def test_invalid_utf8_status_is_a_bad_body() -> None:
    decoder = PlanningDecoder()
    bad = encode_packet(PAYLOAD_STATUS, 0, MISSION_MANAGER, 74, b"\xff\xfe")
    assert decoder.feed(bad + STATUS_OK, now=0.0) == [
        Envelope(112, MISSION_MANAGER, StatusText("OK"))
    ]
    assert decoder.drops["bad_body"] == 1


@given(st.binary(max_size=300).filter(lambda b: SYNC not in b), messages)
@settings(deadline=None)
def test_garbage_without_sync_is_skipped_and_counted(garbage: bytes, msg: PlanningMessage) -> None:
    decoder = PlanningDecoder()
    assert decoder.feed(garbage + encode_message(msg, 1, 2), now=0.0) == [Envelope(1, 2, msg)]
    assert decoder.drops["skipped_bytes"] == len(garbage)


# Bytes biased towards what makes plausible headers: sync, the three types, sizes.
noisy_bytes = st.lists(
    st.sampled_from([SYNC, 0, 1, 2, 3, 9, 0xFF, 0xFE, 0x80]) | st.integers(0, 255),
    max_size=3000,
).map(bytes)


@given(noisy_bytes, st.lists(st.integers(1, 65536), max_size=8))
@settings(deadline=None)
def test_random_bytes_never_raise_and_every_byte_is_accounted(
    data: bytes, chunk_sizes: list[int]
) -> None:
    decoder = PlanningStreamDecoder()
    delivered = 0
    position = 0
    for size in [*chunk_sizes, len(data)]:
        for packet in decoder.feed(data[position : position + size]):
            delivered += HEADER_SIZE + len(packet.body)
        position += size
    assert decoder.buffered < MAX_PACKET_SIZE
    assert decoder.drops["skipped_bytes"] + delivered + decoder.buffered == len(data)


@given(noisy_bytes, st.lists(st.floats() | st.integers(-(10**6), 10**6), max_size=4))
@settings(deadline=None)
def test_planning_decoder_never_raises_and_holds_no_more_than_its_bounds(
    data: bytes, times: list[float]
) -> None:
    decoder = PlanningDecoder(max_pending=2, max_bytes=600, max_age_s=1.0)
    for i, now in enumerate([*times, 0.0]):
        decoder.feed(data[i::2], now=now)
        # What the bounds are for: garbage never makes the decoder hold more.
        assert decoder.reassembler.pending <= 2
        assert decoder.reassembler.pending_bytes <= 600


@given(noisy_bytes, st.lists(envelopes, min_size=1, max_size=3))
@settings(deadline=None, max_examples=50)
def test_garbage_then_messages_never_raises(data: bytes, sent: list[Envelope]) -> None:
    decoder = PlanningDecoder()
    decoder.feed(data, now=0.0)
    decoder.feed(wire_of(sent), now=0.0)
