"""Tests for the targets.bin codec and its atomic writer (thesis 3.1.3)."""

from __future__ import annotations

import math
import os
import re
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fleet.mission.messages import Target
from fleet.mission.targets_file import (
    TARGET_SIZE,
    TargetsFileError,
    decode_targets,
    encode_targets,
    read_targets,
    write_targets,
)

_targets = st.lists(
    st.builds(
        Target,
        lat=st.floats(min_value=-90.0, max_value=90.0),
        lon=st.floats(min_value=-180.0, max_value=180.0),
        alt=st.floats(allow_nan=False, allow_infinity=False),
    ),
    min_size=1,
    max_size=20,
)

BOSTON = Target(lat=42.3601, lon=-71.0942, alt=120.0)
HANSCOM = Target(lat=42.4700, lon=-71.2890, alt=133.0)


def _raw(*records: tuple[float, float, float]) -> bytes:
    return b"".join(struct.pack("<3d", *r) for r in records)


def _names_file_index_offset(err: TargetsFileError, source: str, index: int) -> None:
    message = str(err)
    assert source in message
    assert re.search(rf"\btarget {index}\b", message), message
    assert f"byte offset {index * TARGET_SIZE}" in message
    assert (err.source, err.index, err.offset) == (source, index, index * TARGET_SIZE)


# --- format ----------------------------------------------------------------------


def test_layout_is_three_little_endian_doubles_no_header() -> None:
    data = encode_targets([BOSTON, HANSCOM])
    assert len(data) == 2 * 24
    assert data[:24] == struct.pack("<ddd", 42.3601, -71.0942, 120.0)
    assert data[24:] == struct.pack("<ddd", 42.47, -71.289, 133.0)


@given(_targets)
def test_round_trip_bytes(targets: list[Target]) -> None:
    data = encode_targets(targets)
    assert len(data) == TARGET_SIZE * len(targets)
    decoded = decode_targets(data, "mem")
    # Bit-exact, including -0.0: compare the packed bits, not float equality.
    assert encode_targets(decoded) == data
    assert decoded == targets


@given(_targets)
def test_round_trip_file(targets: list[Target]) -> None:
    # A fresh directory per example: hypothesis reruns the body, pytest's tmp_path would
    # be shared between examples.
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "targets.bin"
        write_targets(path, targets)
        assert read_targets(path) == targets
        assert path.read_bytes() == encode_targets(targets)


def test_boundary_values_are_accepted() -> None:
    edges = [
        Target(90.0, 180.0, 0.0),
        Target(-90.0, -180.0, -0.0),
        Target(0.0, 0.0, -400.0),
    ]
    assert decode_targets(encode_targets(edges), "mem") == edges


# --- refusals when reading -------------------------------------------------------


def test_refuses_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    path.write_bytes(b"")
    with pytest.raises(TargetsFileError, match="no targets") as exc:
        read_targets(path)
    _names_file_index_offset(exc.value, str(path), 0)


def test_refuses_length_not_multiple_of_24(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    path.write_bytes(_raw((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)) + b"\x00" * 5)
    with pytest.raises(TargetsFileError) as exc:
        read_targets(path)
    _names_file_index_offset(exc.value, str(path), 2)
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
    tmp_path: Path, record: tuple[float, float, float], expected: str
) -> None:
    path = tmp_path / "targets.bin"
    # The bad target is the third, so index and offset are not trivially zero.
    path.write_bytes(_raw((1.0, 2.0, 3.0), (4.0, 5.0, 6.0), record, (7.0, 8.0, 9.0)))
    with pytest.raises(TargetsFileError, match=expected) as exc:
        read_targets(path)
    _names_file_index_offset(exc.value, str(path), 2)


def test_is_a_value_error() -> None:
    with pytest.raises(ValueError):
        decode_targets(b"", "x")


def test_missing_file_raises_os_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_targets(tmp_path / "absent.bin")


# --- writing -----------------------------------------------------------------------


def test_write_refuses_what_read_refuses(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    with pytest.raises(TargetsFileError, match="no targets") as exc:
        write_targets(path, [])
    _names_file_index_offset(exc.value, str(path), 0)
    with pytest.raises(TargetsFileError, match=r"latitude 95\.0 is outside") as exc:
        write_targets(path, [BOSTON, Target(95.0, 0.0, 0.0)])
    _names_file_index_offset(exc.value, str(path), 1)
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_failed_validation_leaves_old_file_intact(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, [BOSTON, HANSCOM])
    before = path.read_bytes()
    with pytest.raises(TargetsFileError, match="target 2 at byte offset 48"):
        write_targets(path, [HANSCOM, BOSTON, Target(0.0, math.nan, 0.0)])
    assert path.read_bytes() == before
    assert read_targets(path) == [BOSTON, HANSCOM]
    assert [p.name for p in tmp_path.iterdir()] == ["targets.bin"]


def test_failure_during_write_leaves_old_file_and_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, [BOSTON])
    before = path.read_bytes()

    def failing_fsync(fd: int) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", failing_fsync)
    with pytest.raises(OSError, match="disk full"):
        write_targets(path, [HANSCOM])
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["targets.bin"]


def test_write_replaces_and_keeps_mode(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, [BOSTON, HANSCOM])
    assert os.stat(path).st_mode & 0o777 == 0o644
    os.chmod(path, 0o600)
    write_targets(str(path), [HANSCOM])
    assert read_targets(str(path)) == [HANSCOM]
    assert os.stat(path).st_mode & 0o777 == 0o600
    assert [p.name for p in tmp_path.iterdir()] == ["targets.bin"]


def test_write_accepts_any_iterable(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, (t for t in (BOSTON, HANSCOM)))
    assert read_targets(path) == [BOSTON, HANSCOM]
