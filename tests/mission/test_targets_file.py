"""Tests for the targets.bin codec (thesis 3.1.3): bytes <-> targets, no files."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given

from fleet.mission.messages import Target
from fleet.mission.targets_file import (
    ALTITUDE_ENVELOPE_M,
    MAX_TARGETS,
    TARGET_SIZE,
    TargetsFileError,
    decode_targets,
    encode_targets,
)
from tests.mission.targets_samples import (
    BOSTON,
    HANSCOM,
    names_file_index_offset,
    raw,
    targets_lists,
)

# --- format ----------------------------------------------------------------------


def test_layout_is_three_little_endian_doubles_no_header() -> None:
    data = encode_targets([BOSTON, HANSCOM])
    assert len(data) == 2 * 24
    assert data[:24] == struct.pack("<ddd", 42.3601, -71.0942, 120.0)
    assert data[24:] == struct.pack("<ddd", 42.47, -71.289, 133.0)


@given(targets_lists)
def test_round_trip_bytes(targets: list[Target]) -> None:
    try:
        data = encode_targets(targets)
    except TargetsFileError:
        # Refused only where the bytes would read as text: the decoder refuses them too.
        packed = b"".join(struct.pack("<ddd", t.lat, t.lon, t.alt) for t in targets)
        with pytest.raises(TargetsFileError, match="text file"):
            decode_targets(packed, "mem")
        return
    assert len(data) == TARGET_SIZE * len(targets)
    decoded = decode_targets(data, "mem")
    # Bit-exact, including -0.0: compare the packed bits, not float equality.
    assert encode_targets(decoded) == data
    assert decoded == targets


def test_targets_whose_bytes_all_print_are_refused_both_ways() -> None:
    # Every byte printable: the decoder takes it for a text file, so the encoder refuses it.
    printable = b"AAAAAA@@" * 3  # lat = lon = 32.5, alt = 32.5 m
    target = Target(*struct.unpack("<ddd", printable))
    with pytest.raises(TargetsFileError, match="text file"):
        decode_targets(printable, "mem")
    with pytest.raises(TargetsFileError, match="text file"):
        encode_targets([target])


def test_boundary_values_are_accepted() -> None:
    edges = [
        Target(90.0, 180.0, 0.0),
        Target(-90.0, -180.0, -0.0),
        Target(0.0, 0.0, ALTITUDE_ENVELOPE_M[0]),
        Target(0.0, 0.0, ALTITUDE_ENVELOPE_M[1]),
    ]
    assert decode_targets(encode_targets(edges), "mem") == edges


# --- refusals ----------------------------------------------------------------------


def test_refuses_no_targets() -> None:
    with pytest.raises(TargetsFileError, match="no targets") as exc:
        decode_targets(b"", "targets.bin")
    names_file_index_offset(exc.value, "targets.bin", 0)


def test_refuses_length_not_multiple_of_24() -> None:
    data = raw((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)) + b"\x00" * 5
    with pytest.raises(TargetsFileError, match="not a multiple of 24") as exc:
        decode_targets(data, "targets.bin")
    names_file_index_offset(exc.value, "targets.bin", 2)
    message = str(exc.value)
    assert "length 53" in message
    assert "5 leftover bytes at offset 48" in message
    assert "multiple of 24" in message


def test_refuses_file_shorter_than_one_target() -> None:
    with pytest.raises(TargetsFileError, match=r"length 10 .* 10 leftover bytes at offset 0"):
        decode_targets(b"\x01" * 10, "short.bin")


@pytest.mark.parametrize(
    ("record", "expected"),
    [
        ((math.nan, 0.0, 0.0), r"latitude is nan, expected a finite number"),
        ((0.0, math.inf, 0.0), r"longitude is inf, expected a finite number"),
        ((0.0, 0.0, -math.inf), r"altitude is -inf, expected a finite number"),
        ((0.0, 0.0, math.nan), r"altitude is nan, expected a finite number"),
        ((90.000001, 0.0, 0.0), r"latitude 90.000001 is outside \[-90, 90\]"),
        ((-91.0, 0.0, 0.0), r"latitude -91.0 is outside \[-90, 90\]"),
        ((0.0, 180.5, 0.0), r"longitude 180.5 is outside \[-180, 180\]"),
        ((0.0, -360.0, 0.0), r"longitude -360.0 is outside \[-180, 180\]"),
    ],
)
def test_refuses_bad_values_naming_file_index_offset(
    record: tuple[float, float, float], expected: str
) -> None:
    # The bad target is the third, so index and offset are not trivially zero.
    data = raw((1.0, 2.0, 3.0), (4.0, 5.0, 6.0), record, (7.0, 8.0, 9.0))
    with pytest.raises(TargetsFileError, match=expected) as exc:
        decode_targets(data, "targets.bin")
    names_file_index_offset(exc.value, "targets.bin", 2)


def test_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="no targets"):
        decode_targets(b"", "x")


def test_encode_refuses_what_decode_refuses() -> None:
    with pytest.raises(TargetsFileError, match="no targets"):
        encode_targets([])
    with pytest.raises(TargetsFileError, match=r"target 1 at byte offset 24: latitude 95\.0"):
        encode_targets([BOSTON, Target(95.0, 0.0, 0.0)], source="mem")


# --- a pilot's checks ------------------------------------------------------------------


def test_an_altitude_outside_the_envelope_is_refused_with_its_place() -> None:
    data = raw((42.0, -71.0, 120.0), (42.0, -71.0, -1e9))
    with pytest.raises(
        TargetsFileError, match=r"target 1 at byte offset 24: altitude -1000000000\.0 m is outside"
    ):
        decode_targets(data, "t.bin")


def test_a_text_file_is_named_as_such_not_read_as_targets() -> None:
    csv = b"lat,lon,alt\n35.72,-120.76,600\n35.68,-120.74,600\n35.7500,-120.8000,600.0\n"
    assert len(csv) % TARGET_SIZE == 0  # a whole number of records: only the text check stops it
    with pytest.raises(TargetsFileError, match=r"t\.csv: .* this is a text file .*'lat,lon,alt'"):
        decode_targets(csv, "t.csv")


def test_more_than_the_maximum_targets_a_mission_is_refused() -> None:
    data = raw(*[(42.0, -71.0, 100.0)] * (MAX_TARGETS + 1))
    with pytest.raises(
        TargetsFileError, match=rf"{MAX_TARGETS + 1} targets: at most {MAX_TARGETS}"
    ):
        decode_targets(data, "t.bin")
    with pytest.raises(TargetsFileError, match=r"at most"):
        encode_targets([BOSTON] * (MAX_TARGETS + 1))
