"""Tests for reading and atomically writing targets.bin files (fleet.files.targets_io)."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import given

from fleet.files.targets_io import read_targets, write_targets
from fleet.mission.messages import Target
from fleet.mission.targets_file import TargetsFileError, encode_targets
from tests.mission.targets_samples import (
    BOSTON,
    HANSCOM,
    names_file_index_offset,
    raw,
    targets_lists,
)


@given(targets_lists)
def test_round_trip_file(targets: list[Target]) -> None:
    # A fresh directory per example: hypothesis reruns the body, pytest's tmp_path would
    # be shared between examples.
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "targets.bin"
        write_targets(path, targets)
        assert read_targets(path) == targets
        assert path.read_bytes() == encode_targets(targets)


# --- reading -----------------------------------------------------------------------


def test_refuses_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    path.write_bytes(b"")
    with pytest.raises(TargetsFileError, match="no targets") as exc:
        read_targets(path)
    names_file_index_offset(exc.value, str(path), 0)


def test_refuses_length_not_multiple_of_24(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    path.write_bytes(raw((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)) + b"\x00" * 5)
    with pytest.raises(TargetsFileError, match="not a multiple of 24") as exc:
        read_targets(path)
    names_file_index_offset(exc.value, str(path), 2)
    message = str(exc.value)
    assert "length 53" in message
    assert "5 leftover bytes at offset 48" in message
    assert "multiple of 24" in message


def test_missing_file_raises_os_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"absent\.bin"):
        read_targets(tmp_path / "absent.bin")


# --- writing -----------------------------------------------------------------------


def test_write_refuses_what_read_refuses(tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    with pytest.raises(TargetsFileError, match="no targets") as exc:
        write_targets(path, [])
    names_file_index_offset(exc.value, str(path), 0)
    with pytest.raises(TargetsFileError, match=r"latitude 95\.0 is outside") as exc:
        write_targets(path, [BOSTON, Target(95.0, 0.0, 0.0)])
    names_file_index_offset(exc.value, str(path), 1)
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
