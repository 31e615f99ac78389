from hypothesis import given
from hypothesis import strategies as st

from fleet.piccolo.crc import crc16_arc, crc16_arc_bytes, crc16_arc_follows


def bitwise_crc16_arc(data: bytes) -> int:
    """Textbook reflected CRC-16 (poly 0xA001), independent of the implementation."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def test_check_value() -> None:
    assert crc16_arc(b"123456789") == 0xBB3D
    assert crc16_arc_bytes(b"123456789") == b"\xbb\x3d"


def test_empty_is_initial_value_zero() -> None:
    assert crc16_arc(b"") == 0


@given(st.binary(max_size=600))
def test_matches_bitwise_reference(data: bytes) -> None:
    assert crc16_arc(data) == bitwise_crc16_arc(data)
    assert crc16_arc(bytearray(data)) == crc16_arc(memoryview(data))


@given(st.binary(max_size=8), st.binary(max_size=300), st.binary(max_size=8))
def test_a_trailer_is_found_in_place(before: bytes, data: bytes, after: bytes) -> None:
    buffer = bytearray(before + data + crc16_arc_bytes(data) + after)
    start, stop = len(before), len(before) + len(data)
    assert crc16_arc_follows(buffer, start, stop)
    buffer[stop + 1] ^= 0x01
    assert not crc16_arc_follows(buffer, start, stop)
