from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.mission.messages import (
    BROADCAST,
    MISSION_MANAGER,
    MissionTargets,
    StatusText,
    Target,
    UavResult,
)
from fleet.payload.link import AutopilotEvent, PiccoloLink, PlanningEvent
from fleet.payload.protocol import PlanningMessage, encode_message
from fleet.piccolo.autopilot_messages import UnknownAutopilotMessage
from fleet.piccolo.stream_packet import ALL_OPERATOR_INTERFACES, StreamDecoder
from fleet.piccolo.telemetry import Telemetry, decode_telemetry, encode_telemetry
from fleet.piccolo.waypoint import Waypoint
from tests.support.link_samples import sample_telemetry, sample_waypoint, tracks, waypoints
from tests.support.mixed_stream import mixed_stream

FIXTURES = Path(__file__).parent.parent / "fixtures"


def test_autopilot_messages_round_trip_through_the_link() -> None:
    sender, receiver = PiccoloLink(112), PiccoloLink(0xFFFE)
    sent: list[Telemetry | Waypoint] = [
        sample_telemetry(),
        sample_waypoint(),
        sample_telemetry(2000),
    ]
    wire = b"".join(sender.encode_autopilot(m, ALL_OPERATOR_INTERFACES) for m in sent)
    events = receiver.feed(wire)
    assert all(isinstance(e, AutopilotEvent) for e in events)
    got = [e.message for e in events if isinstance(e, AutopilotEvent)]
    assert got == [decode_telemetry(encode_telemetry(sample_telemetry())), sent[1], got[2]]
    assert events[0].header.source == 112 and events[0].header.stream == 3


@given(st.lists(waypoints | tracks, min_size=1, max_size=8), st.integers(1, 300))
def test_any_chunking_yields_the_same_messages(messages: list[object], chunk: int) -> None:
    sender, receiver = PiccoloLink(74), PiccoloLink(0)
    wire = b"".join(sender.encode_autopilot(m, 74) for m in messages)  # type: ignore[arg-type]
    events = [e for i in range(0, len(wire), chunk) for e in receiver.feed(wire[i : i + chunk])]
    assert [e.message for e in events if isinstance(e, AutopilotEvent)] == messages


def test_autopilot_packet_longer_than_a_stream_packet_is_split() -> None:
    big = UnknownAutopilotMessage(58, bytes(range(255)))  # 261 bytes framed
    sender, receiver = PiccoloLink(112), PiccoloLink(0)
    wire = sender.encode_autopilot(big, 0)
    assert len(StreamDecoder().feed(wire)) == 2
    (event,) = receiver.feed(wire)
    assert isinstance(event, AutopilotEvent) and event.message == big


def test_sequence_counts_bytes_and_ack_echoes_the_peer() -> None:
    a, b = PiccoloLink(1), PiccoloLink(2)
    first = a.encode_autopilot(sample_waypoint(), 2)
    second = a.encode_autopilot(sample_waypoint(1), 2)
    decoder = StreamDecoder()
    p1, p2 = decoder.feed(first + second)
    assert (p1.sequence, p2.sequence) == (24, 48)  # 18 data bytes + 6 framing each
    b.feed(first + second)
    (reply,) = StreamDecoder().feed(b.encode_autopilot(sample_waypoint(), 1))
    assert reply.acknowledge == 48


def test_planning_messages_on_the_payload_stream() -> None:
    sender, receiver = PiccoloLink(112), PiccoloLink(0)
    targets = MissionTargets(
        mission=3,
        team=(74, 112),
        targets=tuple(Target(42.0 + i / 100, -71.0, 90.0) for i in range(30)),
    )
    messages: list[PlanningMessage] = [
        StatusText("OK"),
        targets,
        UavResult(3, 112, (1.5, None, 3.0)),
    ]
    wire = b"".join(
        sender.encode_payload(encode_message(m, 112, BROADCAST if i else MISSION_MANAGER), 0)
        for i, m in enumerate(messages)
    )
    events = [e for i in range(0, len(wire), 7) for e in receiver.feed(wire[i : i + 7])]
    assert [e.envelope.message for e in events if isinstance(e, PlanningEvent)] == messages
    assert all(isinstance(e, PlanningEvent) and e.envelope.source == 112 for e in events)


@settings(max_examples=50, deadline=None)
@given(st.data())
def test_a_flipped_bit_never_yields_a_wrong_message(data: st.DataObject) -> None:
    sender = PiccoloLink(112)
    wire = bytearray(sender.encode_autopilot(sample_telemetry(), 0xFFFE))
    bit = data.draw(st.integers(0, len(wire) * 8 - 1))
    wire[bit // 8] ^= 1 << (bit % 8)
    assert PiccoloLink(0).feed(bytes(wire)) == []


@given(st.binary(max_size=3000))
def test_random_bytes_never_raise_and_the_next_good_packet_gets_through(noise: bytes) -> None:
    link = PiccoloLink(0)
    link.feed(noise)
    # Garbage may end in what looks like the start of a packet; it is dropped once the
    # real packets that follow show it wrong, and they come through.
    good = PiccoloLink(112).encode_autopilot(sample_telemetry(), 0xFFFE)
    events = link.feed(good * 2)
    expected = decode_telemetry(encode_telemetry(sample_telemetry()))
    assert expected in [e.message for e in events if isinstance(e, AutopilotEvent)]


def test_mixed_stream_with_corruption_keeps_the_good_packets() -> None:
    stream = mixed_stream(30.0, corrupt_fraction=0.05, seed=3)
    link = PiccoloLink(0)
    events = link.feed(stream.data)
    drops = link.drop_counters()
    assert stream.corrupted > 0
    # Every corrupted packet is rejected, and only those: resync loses nothing else.
    assert link.stream_decoder.packets == stream.packets - stream.corrupted
    assert drops["stream_bad_crc"] + drops["stream_bad_header_checksum"] > 0
    kinds = {type(e.message).__name__ for e in events if isinstance(e, AutopilotEvent)}
    assert {"Telemetry", "Track", "Waypoint"} <= kinds
    assert len(events) >= stream.messages * 0.85
