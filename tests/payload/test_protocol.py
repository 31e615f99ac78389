"""Tests of the planning protocol end to end: known vectors, round trips, limits."""

import math

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
from fleet.payload.bodies import (
    PAYLOAD_ABORT,
    PAYLOAD_TARGETS,
    PAYLOAD_UAVRESULT,
    PlanningMessage,
    UnknownPlanningMessage,
)
from fleet.payload.framing import (
    HEADER_SIZE,
    MAX_PACKET_SIZE,
    MAX_PAYLOAD_SIZE,
    PAYLOAD_OPM,
    PAYLOAD_STATUS,
    PAYLOAD_UAV,
    SYNC,
    PlanningProtocolError,
    encode_packet,
)
from fleet.payload.protocol import (
    Envelope,
    PlanningDecoder,
    encode_message,
    encode_packets,
)
from fleet.payload.reassembly import MAX_FRAGMENT_SIZE, MAX_MESSAGE_SIZE
from fleet.payload.resync import PlanningStreamDecoder
from tests.payload.planning_samples import (
    ABORT_7,
    RESULT_74,
    STATUS_OK,
    addresses,
    big_mission,
    envelopes,
    messages,
    no_drops,
    wire_of,
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


def test_an_abort_of_one_uav_is_refused_on_the_payload_link() -> None:
    # Its body holds the mission id alone: encoded, it would abort the whole team.
    with pytest.raises(PlanningProtocolError, match="cannot carry one UAV"):
        encode_message(MissionAbort(mission=3, uav=74), source=1, destination=2)
