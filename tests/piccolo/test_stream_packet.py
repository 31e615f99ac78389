import random

from hypothesis import given
from hypothesis import strategies as st

from fleet.piccolo.stream_packet import StreamDecoder, StreamPacket, encode_stream_packet

# A TRACK report (track waypoint 3) from Piccolo 112 to every operator interface,
# written out byte by byte: the autopilot packet is a0 05 0a 02 03 00 + CRC 48 76.
TRACK_CAPTURE = bytes(
    [
        0x5A, 0xA5,  # sync
        0xFF, 0xFE,  # destination: all operator interfaces
        0x00, 0x70,  # source: Piccolo 112
        0x00, 0x08,  # sequence: 8 bytes sent on this stream so far
        0x00, 0x00,  # acknowledge
        0x03,  # stream: autopilot
        0x00,  # flags
        0x08,  # data size
        0x8D,  # XOR of the 13 bytes before
        0xA0, 0x05, 0x0A, 0x02, 0x03, 0x00, 0x48, 0x76,  # TRACK autopilot packet
        0x8B, 0x8B,  # CRC-16/ARC of everything above, high byte first
    ]
)  # fmt: skip

packets = st.builds(
    StreamPacket,
    destination=st.integers(0, 0xFFFF),
    source=st.integers(0, 0xFFFF),
    sequence=st.integers(0, 0xFFFF),
    acknowledge=st.integers(0, 0xFFFF),
    stream=st.integers(0, 0xFF),
    data=st.binary(max_size=255),
    flags=st.integers(0, 0xFF),
)


def test_known_track_capture_decodes() -> None:
    decoder = StreamDecoder()
    (packet,) = decoder.feed(TRACK_CAPTURE)
    assert packet == StreamPacket(0xFFFE, 112, 8, 0, 3, bytes.fromhex("a0050a0203004876"))
    assert encode_stream_packet(packet) == TRACK_CAPTURE


@given(st.lists(packets, min_size=1, max_size=5))
def test_round_trip_several_packets_in_one_chunk(sent: list[StreamPacket]) -> None:
    decoder = StreamDecoder()
    assert decoder.feed(b"".join(encode_stream_packet(p) for p in sent)) == sent
    assert decoder.drops == {"bad_header_checksum": 0, "bad_crc": 0, "skipped_bytes": 0}


@given(packets)
def test_cut_at_every_byte_boundary(packet: StreamPacket) -> None:
    wire = encode_stream_packet(packet)
    for cut in range(len(wire) + 1):
        decoder = StreamDecoder()
        assert decoder.feed(wire[:cut]) + decoder.feed(wire[cut:]) == [packet]


def test_one_byte_at_a_time_and_64k_at_once() -> None:
    rng = random.Random(7)
    sent = [
        StreamPacket(rng.randrange(65536), 74, i, 0, 3, rng.randbytes(rng.randrange(256)))
        for i in range(300)
    ]
    wire = b"".join(encode_stream_packet(p) for p in sent)
    assert len(wire) > 38_000
    bytewise = StreamDecoder()
    got = [p for i in range(len(wire)) for p in bytewise.feed(wire[i : i + 1])]
    assert got == sent
    assert StreamDecoder().feed(wire + wire[: 65536 - len(wire)])[: len(sent)] == sent


@given(st.binary(max_size=2000))
def test_random_bytes_never_raise(noise: bytes) -> None:
    decoder = StreamDecoder()
    decoder.feed(noise)
    # The decoder never holds more than one partial packet.
    assert decoder.buffered <= 271


@given(packets, st.data())
def test_any_single_bit_flip_is_rejected(packet: StreamPacket, data: st.DataObject) -> None:
    wire = bytearray(encode_stream_packet(packet))
    bit = data.draw(st.integers(0, len(wire) * 8 - 1))
    wire[bit // 8] ^= 1 << (bit % 8)
    decoder = StreamDecoder()
    assert packet not in decoder.feed(bytes(wire))
    drops = decoder.drops
    assert drops["bad_header_checksum"] + drops["bad_crc"] + drops["skipped_bytes"] > 0


def test_garbage_between_packets_is_skipped_and_counted() -> None:
    first = StreamPacket(1, 2, 3, 4, 6, b"hello")
    second = StreamPacket(1, 2, 8, 4, 6, b"world")
    wire = (
        b"\x00\x5a\x11"
        + encode_stream_packet(first)
        + b"\x5a\xa5zzzz"
        + encode_stream_packet(second)
    )
    decoder = StreamDecoder()
    assert decoder.feed(wire) == [first, second]
    assert decoder.drops["skipped_bytes"] == 9
    assert decoder.drops["bad_header_checksum"] == 1


def test_corrupt_crc_then_valid_packet_resynchronises() -> None:
    good = encode_stream_packet(StreamPacket(1, 2, 3, 4, 3, b"abc"))
    bad = bytearray(good)
    bad[-1] ^= 0xFF
    decoder = StreamDecoder()
    assert len(decoder.feed(bytes(bad) + good)) == 1
    assert decoder.drops["bad_crc"] == 1
