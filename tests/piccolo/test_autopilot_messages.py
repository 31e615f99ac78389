import math
import struct

from hypothesis import given
from hypothesis import strategies as st

from fleet.piccolo.autopilot_messages import (
    UnknownAutopilotMessage,
    decode_autopilot_message,
    encode_autopilot_message,
)
from fleet.piccolo.autopilot_packet import (
    AutopilotPacket,
    AutopilotPacketDecoder,
    encode_autopilot_packet,
)
from fleet.piccolo.telemetry import (
    FLAG_AGL,
    FLAG_FUEL,
    FLAG_GPS,
    FLAG_MAGNETOMETER,
    FLAG_RAW,
    FLAG_SENSOR,
    decode_telemetry,
    encode_telemetry,
)
from fleet.piccolo.track import Track, decode_track
from fleet.piccolo.waypoint import Waypoint, decode_waypoint, encode_waypoint
from tests.support.link_samples import sample_telemetry, tracks, waypoints

i16 = st.integers(-0x8000, 0x7FFF)
u16 = st.integers(0, 0xFFFF)


@st.composite
def raw_telemetry(draw: st.DrawFn) -> bytes:
    """Valid TELEMETRY_HI_RES data bytes built from raw wire fields."""
    block_flags = draw(
        st.sets(st.sampled_from([FLAG_GPS, FLAG_SENSOR, FLAG_RAW, FLAG_MAGNETOMETER, FLAG_AGL]))
    )
    actuators = draw(st.lists(u16, max_size=8))
    fuel = draw(st.none() | st.floats(width=16, allow_nan=False, allow_infinity=False))
    flags = sum(block_flags) | len(actuators) | (FLAG_FUEL if fuel is not None else 0)
    out = struct.pack(">HHI", flags, draw(u16), draw(st.integers(0, 2**32 - 1)))
    if FLAG_GPS in block_flags:
        out += struct.pack(
            ">ii3sBHhhhHHI",
            draw(st.integers(-90 * 3_600_000, 90 * 3_600_000)),
            draw(st.integers(-180 * 3_600_000, 180 * 3_600_000)),
            draw(st.integers(0, 2**24 - 1)).to_bytes(3, "big"),
            draw(st.integers(0, 255)),
            draw(u16),
            draw(i16),
            draw(i16),
            draw(i16),
            draw(u16),
            draw(u16),
            draw(st.integers(0, 2**32 - 1)),
        )
    if FLAG_SENSOR in block_flags:
        out += struct.pack(
            ">hhhhhhHHBbHH",
            *(draw(i16) for _ in range(6)),
            draw(u16),
            draw(u16),
            draw(st.integers(0, 255)),
            draw(st.integers(-128, 127)),
            draw(u16),
            draw(u16),
        )
    if FLAG_RAW in block_flags:
        out += struct.pack(">6h", *(draw(i16) for _ in range(6)))
    if FLAG_MAGNETOMETER in block_flags:
        out += struct.pack(">hhhH", draw(i16), draw(i16), draw(i16), draw(u16))
    if FLAG_AGL in block_flags:
        out += struct.pack(">H", draw(u16))
    out += struct.pack(f">{len(actuators)}H", *actuators)
    if fuel is not None:
        out += struct.pack(">e", fuel)
    return out + draw(st.binary(max_size=6))


@given(raw_telemetry())
def test_telemetry_wire_round_trip_is_byte_exact(data: bytes) -> None:
    assert encode_telemetry(decode_telemetry(data)) == data


def test_telemetry_units() -> None:
    data = (
        struct.pack(">HHI", FLAG_GPS | FLAG_SENSOR, 0, 12345)
        + struct.pack(
            ">ii3sBHhhhHHI",
            3_600_000 * 42,  # 42 degrees in milli-arcseconds
            -3_600_000 * 71 - 1_800_000,  # -71.5 degrees
            (113_050).to_bytes(3, "big"),  # 1130.50 m raw -> 130.5 m
            0,
            (5 << 10) | (9 << 5) | 8,
            -150,  # -1.5 m/s north
            2200,  # 22 m/s east
            10,
            0xE000,
            2300,
            777,
        )
        + struct.pack(">hhhhhhHHBbHH", 5236, 0, 15708, 0, 100, -200, 0, 0, 200, 20, 4500, 50000)
    )
    message = decode_telemetry(data)
    assert message.system_time_ms == 12345
    assert message.gps is not None and message.sensor is not None
    assert message.gps.lat == 42.0 and message.gps.lon == -71.5
    assert math.isclose(message.gps.alt, 130.5)
    assert (message.gps.vel_north, message.gps.vel_east, message.gps.vel_down) == (-1.5, 22.0, 0.1)
    assert math.isclose(message.gps.dop, 1.0) and message.gps.sats_visible == 9
    assert math.isclose(message.sensor.roll, 30.0, abs_tol=0.01)
    assert math.isclose(message.sensor.yaw, 90.0, abs_tol=0.01)
    assert message.sensor.indicated_airspeed == 25.0
    assert (message.sensor.wind_south, message.sensor.wind_west) == (1.0, -2.0)
    assert message.sensor.static_pressure == 100000.0
    assert message.raw is None and message.agl is None


def test_missing_block_moves_later_blocks_up() -> None:
    only_agl = struct.pack(">HHI", FLAG_AGL, 0, 1) + struct.pack(">H", 4321)
    assert decode_telemetry(only_agl).agl == 43.21


def test_truncated_telemetry_passes_through_as_unknown_with_reason() -> None:
    data = encode_telemetry(sample_telemetry())[:-10]
    message = decode_autopilot_message(AutopilotPacket(69, data))
    assert isinstance(message, UnknownAutopilotMessage)
    assert message.error is not None and "too short" in message.error


@given(waypoints)
def test_waypoint_round_trip(waypoint: Waypoint) -> None:
    data = encode_waypoint(waypoint)
    assert len(data) == 18
    assert decode_waypoint(data) == waypoint


@given(tracks)
def test_track_round_trip(track: Track) -> None:
    assert (
        decode_autopilot_message(AutopilotPacket(10, bytes((track.waypoint, track.go_to)))) == track
    )
    assert decode_track(encode_autopilot_message(track)[4:6]) == track


def test_unknown_type_passes_through() -> None:
    message = UnknownAutopilotMessage(58, b"\x01\x02\x03")
    wire = encode_autopilot_message(message)
    (packet,) = AutopilotPacketDecoder().feed(wire)
    assert decode_autopilot_message(packet) == message


def test_decoder_handles_packets_spanning_and_sharing_chunks() -> None:
    sent = [sample_telemetry(i) for i in range(5)]
    wire = b"".join(encode_autopilot_message(m) for m in sent)
    decoder = AutopilotPacketDecoder()
    got: list[object] = []
    for start in range(0, len(wire), 37):
        got.extend(decode_autopilot_message(p) for p in decoder.feed(wire[start : start + 37]))
    assert got == [decode_telemetry(encode_telemetry(m)) for m in sent]
    assert decoder.buffered == 0


def test_decoder_drops_bad_crc_and_resynchronises() -> None:
    good = encode_autopilot_packet(10, b"\x04\x00")
    bad = bytearray(good)
    bad[4] ^= 0x01
    decoder = AutopilotPacketDecoder()
    assert decoder.feed(b"junk" + bytes(bad) + good) == [AutopilotPacket(10, b"\x04\x00")]
    assert decoder.drops == {"bad_crc": 1, "skipped_bytes": 4 + len(bad)}
