"""Tests of segmenting and reassembling PAYLOAD_UAV messages (fleet.payload.reassembly)."""

import math
import random

from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.mission.messages import (
    BROADCAST,
    MISSION_MANAGER,
    MissionTargets,
)
from fleet.payload.bodies import (
    PAYLOAD_ABORT,
    UnknownPlanningMessage,
)
from fleet.payload.framing import (
    MAX_PACKET_SIZE,
    PAYLOAD_STATUS,
    PAYLOAD_UAV,
    PlanningPacket,
    encode_packet,
)
from fleet.payload.protocol import (
    Envelope,
    PlanningDecoder,
    encode_packets,
)
from fleet.payload.reassembly import MAX_FRAGMENT_SIZE, MAX_MESSAGE_SIZE, SegmentReassembler
from tests.payload.planning_samples import (
    big_mission,
    no_drops,
)

# ---------------------------------------------------------------- segmentation


def mission_packets(
    msg: MissionTargets | None = None, source: int = MISSION_MANAGER, seq: int = 0
) -> list[bytes]:
    return encode_packets(msg or big_mission(), source, BROADCAST, seq)


@given(st.permutations(range(6)))
@settings(deadline=None)
def test_segments_out_of_order(order: list[int]) -> None:
    packets = mission_packets()
    assert len(packets) == 6
    decoder = PlanningDecoder()
    got = [e for i in order for e in decoder.feed(packets[i], now=0.0)]
    assert got == [Envelope(MISSION_MANAGER, BROADCAST, big_mission())]
    assert no_drops(decoder)


# Extras never hold all six indices: a complete second copy would be a resend, and a
# resend is delivered again by design.
@given(
    st.lists(st.integers(0, 5), min_size=1, max_size=20).filter(lambda e: len(set(e)) < 6),
    st.randoms(),
)
@settings(deadline=None)
def test_duplicated_segments_deliver_once(extra: list[int], rng: random.Random) -> None:
    packets = mission_packets()
    order = list(range(6)) + extra
    rng.shuffle(order)
    decoder = PlanningDecoder()
    got = decoder.feed(b"".join(packets[i] for i in order), now=0.0)
    # A duplicate arriving after completion opens a fresh partial message that cannot
    # complete: it ages out, counted, and is never delivered.
    assert got == [Envelope(MISSION_MANAGER, BROADCAST, big_mission())]
    drops = decoder.drops
    assert drops["duplicate_segment"] + decoder.reassembler.pending >= 1


def test_duplicate_within_pending_is_counted() -> None:
    packets = mission_packets()
    decoder = PlanningDecoder()
    assert decoder.feed(packets[0] + packets[0] + packets[1], now=0.0) == []
    assert decoder.drops["duplicate_segment"] == 1
    assert len(decoder.feed(b"".join(packets[2:]), now=0.0)) == 1


def test_missing_segment_is_never_delivered_and_expires() -> None:
    packets = mission_packets()
    decoder = PlanningDecoder(max_age_s=10.0)
    assert decoder.feed(b"".join(packets[:3] + packets[4:]), now=100.0) == []
    assert decoder.reassembler.pending == 1
    assert decoder.feed(b"", now=110.0) == []  # exactly the age limit: still held
    assert decoder.reassembler.pending == 1
    assert decoder.feed(b"", now=110.5) == []
    assert decoder.reassembler.pending == 0
    assert decoder.reassembler.pending_bytes == 0
    assert decoder.drops["expired_message"] == 1
    # The missing segment arriving late cannot complete anything.
    assert decoder.feed(packets[3], now=111.0) == []


def test_clock_going_backwards_does_not_raise_or_expire() -> None:
    packets = mission_packets()
    decoder = PlanningDecoder(max_age_s=1.0)
    decoder.feed(packets[0], now=50.0)
    decoder.feed(packets[1], now=-1e9)
    decoder.feed(b"", now=math.nan)
    assert decoder.reassembler.pending == 1
    assert len(decoder.feed(b"".join(packets[2:]), now=50.5)) == 1


def test_interleaved_messages_from_different_senders() -> None:
    a = mission_packets(big_mission(mission=1), source=74)
    b = mission_packets(big_mission(mission=2), source=112)
    decoder = PlanningDecoder()
    got = decoder.feed(b"".join(x + y for x, y in zip(a, b, strict=True)), now=0.0)
    assert [(e.source, e.message) for e in got] == [
        (74, big_mission(mission=1)),
        (112, big_mission(mission=2)),
    ]


def test_interleaved_messages_from_one_sender_with_distinct_seq() -> None:
    a = mission_packets(big_mission(mission=1), seq=1)
    b = mission_packets(big_mission(mission=2), seq=2)
    got = PlanningDecoder().feed(b"".join(x + y for x, y in zip(a, b, strict=True)), now=0.0)
    assert [e.message for e in got] == [big_mission(mission=1), big_mission(mission=2)]


def test_reused_seq_after_a_loss_restarts_the_message() -> None:
    first = mission_packets(big_mission(mission=1))
    second = mission_packets(big_mission(mission=2))
    decoder = PlanningDecoder()
    got = decoder.feed(b"".join(first[:5] + second), now=0.0)  # first lost its last segment
    assert [e.message for e in got] == [big_mission(mission=2)]
    assert decoder.drops["inconsistent_message"] == 1
    assert decoder.reassembler.pending == 0


def test_segment_count_mismatch_is_inconsistent() -> None:
    six = mission_packets(big_mission(60))
    three = mission_packets(big_mission(30))
    assert len(three) == 3
    decoder = PlanningDecoder()
    got = decoder.feed(six[0] + six[1] + b"".join(three), now=0.0)
    assert [e.message for e in got] == [big_mission(30)]
    assert decoder.drops["inconsistent_message"] == 1


def test_reassembler_bounds_pending_messages() -> None:
    decoder = PlanningDecoder(max_pending=2)
    for source in (1, 2, 3):
        decoder.feed(mission_packets(source=source)[0], now=0.0)
    assert decoder.reassembler.pending == 2
    assert decoder.drops["evicted_message"] == 1
    # The oldest (source 1) went; source 3 can still complete.
    assert [e.source for e in decoder.feed(b"".join(mission_packets(source=3)[1:]), 0.0)] == [3]


def test_reassembler_bounds_bytes() -> None:
    decoder = PlanningDecoder(max_bytes=3 * MAX_FRAGMENT_SIZE)
    decoder.feed(b"".join(mission_packets(source=1)[:2]), now=0.0)
    decoder.feed(b"".join(mission_packets(source=2)[:2]), now=0.0)
    assert decoder.reassembler.pending == 1
    assert decoder.reassembler.pending_bytes == 2 * MAX_FRAGMENT_SIZE
    assert decoder.drops["evicted_message"] == 1


def test_reassembler_rejects_bad_segments_without_raising() -> None:
    reassembler = SegmentReassembler()
    bad = [
        PlanningPacket(PAYLOAD_UAV, 1, 0, 0, b"\x00"),  # truncated segment header
        PlanningPacket(PAYLOAD_UAV, 1, 0, 0, b"\x00\x00\x00\x00"),  # count 0
        PlanningPacket(PAYLOAD_UAV, 1, 0, 0, b"\x00\x00\x02\x02"),  # index >= count
        PlanningPacket(PAYLOAD_UAV, 1, 0, 0, b"\x00\x00\x00\x02abc"),  # short non-final
        PlanningPacket(PAYLOAD_UAV, 1, 0, 0, b"\x00\x00\x01\x02"),  # empty final
        PlanningPacket(PAYLOAD_STATUS, 0, 0, 0, b"hi"),  # not PAYLOAD_UAV
    ]
    assert [reassembler.push(p, now=0.0) for p in bad] == [None] * len(bad)
    assert reassembler.drops["bad_segment"] == len(bad)


def test_reassembled_known_message_that_does_not_decode_is_bad_message() -> None:
    # Two well-formed segments whose joined bytes are not a PAYLOAD_ABORT body.
    body = bytes(MAX_FRAGMENT_SIZE + 1)
    wire = b"".join(
        encode_packet(PAYLOAD_UAV, PAYLOAD_ABORT, BROADCAST, 1, bytes([0, 0, i, 2]) + part)
        for i, part in enumerate([body[:MAX_FRAGMENT_SIZE], body[MAX_FRAGMENT_SIZE:]])
    )
    decoder = PlanningDecoder()
    assert decoder.feed(wire, now=0.0) == []
    assert decoder.drops["bad_message"] == 1


def test_unknown_user_code_is_passed_through_segmented() -> None:
    msg = UnknownPlanningMessage(PAYLOAD_UAV, 0x42, bytes(range(256)) * 3)
    packets = encode_packets(msg, 74, 112, seq=300)
    assert len(packets) == 4
    assert PlanningDecoder().feed(b"".join(packets), now=0.0) == [Envelope(74, 112, msg)]


def test_largest_message_fits_exactly_255_segments() -> None:
    msg = UnknownPlanningMessage(PAYLOAD_UAV, 0x42, bytes(MAX_MESSAGE_SIZE))
    packets = encode_packets(msg, 1, 2)
    assert len(packets) == 255
    assert all(len(p) == MAX_PACKET_SIZE for p in packets)
    assert PlanningDecoder().feed(b"".join(packets), now=0.0) == [Envelope(1, 2, msg)]
