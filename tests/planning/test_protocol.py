import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.mission.messages import (
    BROADCAST,
    MISSION_MANAGER,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    Target,
    UavResult,
)
from fleet.planning.bodies import (
    PAYLOAD_ABORT,
    PAYLOAD_TARGETS,
    PAYLOAD_UAVRESULT,
    PlanningMessage,
    UnknownPlanningMessage,
)
from fleet.planning.framing import (
    HEADER_SIZE,
    MAX_PACKET_SIZE,
    MAX_PAYLOAD_SIZE,
    PAYLOAD_OPM,
    PAYLOAD_STATUS,
    PAYLOAD_UAV,
    SYNC,
    PlanningPacket,
    PlanningProtocolError,
    encode_packet,
)
from fleet.planning.protocol import (
    Envelope,
    PlanningDecoder,
    encode_message,
    encode_packets,
)
from fleet.planning.reassembly import MAX_FRAGMENT_SIZE, MAX_MESSAGE_SIZE, SegmentReassembler
from fleet.planning.resync import PlanningStreamDecoder

# Thesis 2.9's own example: a PAYLOAD_STATUS "OK" has size two. From Piccolo 112 to
# the Mission Manager, written out byte by byte.
STATUS_OK = bytes(
    [
        0xB5,  # sync
        0x02,  # size: two text bytes, no NUL
        0x01,  # type: PAYLOAD_STATUS
        0x00,  # user: unused for status
        0xFE, 0xFF,  # destination: Mission Manager (0xFFFE, little-endian)
        0x70, 0x00,  # source: Piccolo 112
        0x4F, 0x4B,  # "OK"
    ]
)  # fmt: skip

# UAV 74's result for mission 3: 1.5 s to target 0, no answer for target 1, broadcast.
RESULT_74 = bytes(
    [
        0xB5,  # sync
        0x1C,  # size: 4 segment header + 8 result header + 2 x 8 times = 28
        0x02,  # type: PAYLOAD_UAV
        0x02,  # user: PAYLOAD_UAVRESULT
        0xFF, 0xFF,  # destination: broadcast
        0x4A, 0x00,  # source: Piccolo 74
        0x05, 0x00,  # segment: message seq 5
        0x00,  # segment index 0
        0x01,  # segment count 1
        0x03, 0x00, 0x00, 0x00,  # mission 3 (u32)
        0x4A, 0x00,  # uav 74 (u16)
        0x02, 0x00,  # 2 times (u16)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x3F,  # 1.5 (f64)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x7F,  # NaN: None
    ]
)  # fmt: skip

# The ground aborts mission 7 on every UAV.
ABORT_7 = bytes(
    [
        0xB5, 0x08, 0x02, 0x03,  # sync, size 8, PAYLOAD_UAV, PAYLOAD_ABORT
        0xFF, 0xFF, 0xFE, 0xFF,  # to broadcast, from the Mission Manager
        0x00, 0x00, 0x00, 0x01,  # seq 0, segment 0 of 1
        0x07, 0x00, 0x00, 0x00,  # mission 7
    ]
)  # fmt: skip

addresses = st.integers(0, 0xFFFF)
finite = st.floats(allow_nan=False, allow_infinity=False)
targets = st.builds(
    Target,
    lat=finite,
    lon=finite,
    # Altitude travels as f32 (thesis 4.2): only f32 values come back unchanged.
    alt=st.floats(width=32, allow_nan=False, allow_infinity=False),
)
opm_commands = st.builds(
    OpmCommand,
    enabled=st.booleans(),
    status_rate_hz=st.floats(min_value=0, allow_infinity=False),
)
mission_targets = st.builds(
    MissionTargets,
    mission=st.integers(0, 0xFFFF_FFFF),
    team=st.lists(addresses, max_size=40).map(tuple),
    targets=st.lists(targets, max_size=70).map(tuple),
    deadline_s=st.floats(min_value=0, allow_infinity=False),
)
uav_results = st.builds(
    UavResult,
    mission=st.integers(0, 0xFFFF_FFFF),
    uav=addresses,
    times=st.lists(st.none() | st.floats(allow_nan=False), max_size=100).map(tuple),
)
aborts = st.builds(MissionAbort, mission=st.integers(0, 0xFFFF_FFFF))
unknowns = st.builds(
    UnknownPlanningMessage,
    type=st.just(PAYLOAD_UAV),
    user=st.integers(0, 0xFF).filter(lambda u: u not in (1, 2, 3)),
    body=st.binary(max_size=700),
)
# Short enough (<= 60 code points, <= 240 bytes) to travel as one status packet.
short_status = st.builds(StatusText, text=st.text(max_size=60))
messages: st.SearchStrategy[PlanningMessage] = st.one_of(
    opm_commands, short_status, mission_targets, uav_results, aborts, unknowns
)
envelopes = st.builds(Envelope, source=addresses, destination=addresses, message=messages)


def wire_of(sent: list[Envelope]) -> bytes:
    # A distinct seq per message, as a sender with several messages in flight must use.
    return b"".join(
        encode_message(e.message, e.source, e.destination, seq=i) for i, e in enumerate(sent)
    )


def no_drops(decoder: PlanningDecoder) -> bool:
    return not any(decoder.drops.values())


def big_mission(n_targets: int = 60, n_team: int = 30, mission: int = 9) -> MissionTargets:
    return MissionTargets(
        mission=mission,
        team=tuple(range(100, 100 + n_team)),
        targets=tuple(Target(42.36 + i * 1e-3, -71.09 - i * 1e-3, 120.5) for i in range(n_targets)),
        deadline_s=12.5,
    )


# ---------------------------------------------------------------- known vectors


@pytest.mark.parametrize(
    ("wire", "envelope"),
    [
        (STATUS_OK, Envelope(112, MISSION_MANAGER, StatusText("OK"))),
        (RESULT_74, Envelope(74, BROADCAST, UavResult(3, 74, (1.5, None)))),
        (ABORT_7, Envelope(MISSION_MANAGER, BROADCAST, MissionAbort(7))),
    ],
)
def test_known_vectors(wire: bytes, envelope: Envelope) -> None:
    seq = 5 if wire is RESULT_74 else 0
    assert encode_message(envelope.message, envelope.source, envelope.destination, seq) == wire
    decoder = PlanningDecoder()
    assert decoder.feed(wire, now=0.0) == [envelope]
    assert no_drops(decoder)


def test_opm_layout() -> None:
    wire = encode_message(OpmCommand(enabled=True, status_rate_hz=2.0), MISSION_MANAGER, 112)
    assert wire == bytes.fromhex("b5 09 00 00 7000 feff 01 0000000000000040")


def test_packet_fields_from_stream_decoder() -> None:
    (packet,) = PlanningStreamDecoder().feed(RESULT_74)
    assert (packet.type, packet.user, packet.destination, packet.source) == (
        PAYLOAD_UAV,
        PAYLOAD_UAVRESULT,
        BROADCAST,
        74,
    )
    assert packet.body == RESULT_74[HEADER_SIZE:]


# ---------------------------------------------------------------- round trips


@given(st.lists(envelopes, min_size=1, max_size=6))
@settings(deadline=None, max_examples=60)
def test_round_trip_several_messages_in_one_chunk(sent: list[Envelope]) -> None:
    decoder = PlanningDecoder()
    assert decoder.feed(wire_of(sent), now=0.0) == sent
    assert no_drops(decoder)
    assert decoder.reassembler.pending == 0


@given(messages, addresses, addresses, st.integers(0, 0xFFFF))
@settings(deadline=None, max_examples=150)
def test_round_trip_every_message_and_packet_limits(
    msg: PlanningMessage, source: int, destination: int, seq: int
) -> None:
    packets = encode_packets(msg, source, destination, seq)
    assert all(HEADER_SIZE <= len(p) <= MAX_PACKET_SIZE for p in packets)
    assert all(p[0] == SYNC and p[1] == len(p) - HEADER_SIZE for p in packets)
    decoder = PlanningDecoder()
    assert decoder.feed(b"".join(packets), now=1.0) == [Envelope(source, destination, msg)]


@pytest.mark.parametrize("n_targets", [0, 1, 60])
@pytest.mark.parametrize("n_team", [1, 30])
def test_targets_sizes(n_targets: int, n_team: int) -> None:
    msg = big_mission(n_targets, n_team)
    packets = encode_packets(msg, MISSION_MANAGER, BROADCAST, seq=7)
    app_size = 4 + 8 + 2 + 2 * n_team + 2 + 20 * n_targets
    assert len(packets) == max(1, math.ceil(app_size / MAX_FRAGMENT_SIZE))
    assert sum(len(p) - HEADER_SIZE - 4 for p in packets) == app_size
    decoder = PlanningDecoder()
    assert decoder.feed(b"".join(packets), now=0.0) == [Envelope(MISSION_MANAGER, BROADCAST, msg)]
    assert no_drops(decoder)


def test_result_times_travel_bit_for_bit() -> None:
    times = (0.0, -0.0, math.inf, -math.inf, 5e-324, 1.7976931348623157e308, None, 0.1)
    msg = UavResult(mission=1, uav=112, times=times)
    (envelope,) = PlanningDecoder().feed(encode_message(msg, 112, BROADCAST), now=0.0)
    got = envelope.message
    assert isinstance(got, UavResult)
    assert [None if t is None else math.copysign(1, t) for t in got.times] == [
        None if t is None else math.copysign(1, t) for t in times
    ]
    assert got == msg


def test_any_nan_pattern_decodes_as_none() -> None:
    # A signalling NaN with payload, not the canonical one the encoder writes.
    body = (
        bytes.fromhex("0000 00 01")
        + bytes.fromhex("01000000 4a00 0100")
        + bytes.fromhex("0100000000 00f0 7f")
    )
    wire = encode_packet(PAYLOAD_UAV, PAYLOAD_UAVRESULT, BROADCAST, 74, body)
    (envelope,) = PlanningDecoder().feed(wire, now=0.0)
    assert envelope.message == UavResult(mission=1, uav=74, times=(None,))


# ---------------------------------------------------------------- status text


def test_status_non_ascii_round_trip() -> None:
    text = "Cible atteinte ✓ — 12 µs, 日本語, 🚀"
    wire = encode_message(StatusText(text), 74, MISSION_MANAGER)
    assert wire[1] == len(text.encode("utf-8"))
    (envelope,) = PlanningDecoder().feed(wire, now=0.0)
    assert envelope.message == StatusText(text)


def test_empty_status_is_a_zero_size_packet() -> None:
    wire = encode_message(StatusText(""), 74, MISSION_MANAGER)
    assert wire == bytes.fromhex("b5 00 01 00 feff 4a00")
    assert PlanningDecoder().feed(wire, now=0.0) == [Envelope(74, MISSION_MANAGER, StatusText(""))]


@given(st.text(max_size=400))
@settings(deadline=None)
def test_long_status_splits_at_code_points(text: str) -> None:
    packets = encode_packets(StatusText(text), 74, MISSION_MANAGER)
    assert all(len(p) - HEADER_SIZE <= MAX_PAYLOAD_SIZE for p in packets)
    # Every piece but the last is as full as a code-point boundary allows.
    assert all(len(p) - HEADER_SIZE > MAX_PAYLOAD_SIZE - 4 for p in packets[:-1])
    got = PlanningDecoder().feed(b"".join(packets), now=0.0)
    assert len(got) == len(packets)
    assert "".join(e.message.text for e in got if isinstance(e.message, StatusText)) == text


def test_status_split_never_cuts_a_four_byte_character() -> None:
    text = "a" + "🚀" * 100  # 401 bytes: the 255-byte boundary falls inside an emoji
    packets = encode_packets(StatusText(text), 74, MISSION_MANAGER)
    assert [len(p) - HEADER_SIZE for p in packets] == [253, 148]
    assert [p[HEADER_SIZE:].decode("utf-8") for p in packets] == ["a" + "🚀" * 63, "🚀" * 37]


# ---------------------------------------------------------------- stream framing


def sample_stream() -> tuple[bytes, list[Envelope]]:
    sent = [
        Envelope(MISSION_MANAGER, 74, OpmCommand(True, 0.5)),
        Envelope(74, MISSION_MANAGER, StatusText("MILP solved in 0.8 s ✓")),
        Envelope(MISSION_MANAGER, BROADCAST, big_mission(20, 2)),  # 2 segments
        Envelope(112, BROADCAST, UavResult(9, 112, (3.0, None, 41.25))),
        Envelope(MISSION_MANAGER, BROADCAST, MissionAbort(9)),
        Envelope(74, 112, UnknownPlanningMessage(PAYLOAD_UAV, 0x80, b"\xb5" * 300)),
    ]
    return wire_of(sent), sent


def test_cut_at_every_byte_boundary() -> None:
    wire, sent = sample_stream()
    for cut in range(len(wire) + 1):
        decoder = PlanningDecoder()
        got = decoder.feed(wire[:cut], now=0.0) + decoder.feed(wire[cut:], now=0.0)
        assert got == sent, cut
        assert no_drops(decoder)


def test_one_byte_at_a_time() -> None:
    wire, sent = sample_stream()
    decoder = PlanningDecoder()
    got = [e for i in range(len(wire)) for e in decoder.feed(wire[i : i + 1], now=0.0)]
    assert got == sent
    assert decoder.stream.buffered == 0


def test_64k_chunk() -> None:
    wire, sent = sample_stream()
    repeats = 65536 // len(wire)
    decoder = PlanningDecoder()
    assert decoder.feed(wire * repeats, now=0.0) == sent * repeats
    assert no_drops(decoder)


@given(st.data())
@settings(deadline=None, max_examples=50)
def test_arbitrary_chunking(data: st.DataObject) -> None:
    wire, sent = sample_stream()
    cuts = sorted(data.draw(st.lists(st.integers(0, len(wire)), max_size=30)))
    decoder = PlanningDecoder()
    got = []
    for start, stop in zip([0, *cuts], [*cuts, len(wire)], strict=True):
        got += decoder.feed(wire[start:stop], now=0.0)
    assert got == sent


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
def test_planning_decoder_never_raises(data: bytes, times: list[float]) -> None:
    decoder = PlanningDecoder(max_pending=2, max_bytes=600, max_age_s=1.0)
    for i, now in enumerate([*times, 0.0]):
        decoder.feed(data[i::2], now=now)
    assert all(v >= 0 for v in decoder.drops.values())


@given(noisy_bytes, st.lists(envelopes, min_size=1, max_size=3))
@settings(deadline=None, max_examples=50)
def test_garbage_then_messages_never_raises(data: bytes, sent: list[Envelope]) -> None:
    decoder = PlanningDecoder()
    decoder.feed(data, now=0.0)
    decoder.feed(wire_of(sent), now=0.0)


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


# ---------------------------------------------------------------- limits


@pytest.mark.parametrize(
    ("msg", "kwargs", "limit"),
    [
        (big_mission(3300, 1), {}, "255 segments"),
        (MissionTargets(1, tuple([1] * 70000), ()), {}, "team count allows 65535"),
        (MissionTargets(1, (0x10000,), ()), {}, "u16"),
        (MissionTargets(2**32, (), ()), {}, "mission .* u32"),
        (MissionTargets(1, (), (), deadline_s=math.inf), {}, "deadline_s"),
        (MissionTargets(1, (), (Target(math.nan, 0, 0),)), {}, "lat"),
        (MissionTargets(1, (), (Target(0, 0, 1e39),)), {}, "f32"),
        (UavResult(1, 2, (math.nan,)), {}, "NaN"),
        (UavResult(1, 0x10000, ()), {}, "uav"),
        (UavResult(1, 2, (None,) * 70000), {}, "count allows 65535"),
        (MissionAbort(-1), {}, "mission"),
        (MissionAbort(1), {"seq": 0x10000}, "seq"),
        (MissionAbort(1), {"source": 0x10000}, "source"),
        (MissionAbort(1), {"destination": -1}, "destination"),
        (OpmCommand(True, -1.0), {}, "status_rate_hz"),
        (StatusText("\ud800"), {}, "UTF-8"),
        (UnknownPlanningMessage(PAYLOAD_UAV, PAYLOAD_TARGETS, b""), {}, "known message"),
        (UnknownPlanningMessage(PAYLOAD_STATUS, 0x42, b""), {}, "PAYLOAD_UAV"),
        (UnknownPlanningMessage(PAYLOAD_UAV, 0x42, bytes(MAX_MESSAGE_SIZE + 1)), {}, "64005"),
    ],
)
def test_unrepresentable_messages_raise(
    msg: PlanningMessage, kwargs: dict[str, int], limit: str
) -> None:
    args = {"source": 1, "destination": 2, "seq": 0, **kwargs}
    with pytest.raises(PlanningProtocolError, match=limit):
        encode_message(msg, **args)


def test_not_a_message_raises() -> None:
    with pytest.raises(PlanningProtocolError, match="Target"):
        encode_message(Target(0, 0, 0), 1, 2)  # type: ignore[arg-type]


def test_encode_packet_refuses_oversize_body() -> None:
    with pytest.raises(PlanningProtocolError, match="255"):
        encode_packet(PAYLOAD_STATUS, 0, 1, 2, bytes(256))


def test_constants_are_fixed() -> None:
    # Changing any of these breaks every deployed peer: this test is the tripwire.
    assert (SYNC, PAYLOAD_OPM, PAYLOAD_STATUS, PAYLOAD_UAV) == (0xB5, 0, 1, 2)
    assert (PAYLOAD_TARGETS, PAYLOAD_UAVRESULT, PAYLOAD_ABORT) == (1, 2, 3)
    assert (MAX_FRAGMENT_SIZE, MAX_MESSAGE_SIZE) == (251, 64005)
