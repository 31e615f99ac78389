"""MCAP files that survive their writer's death, rotation, and reading them back."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet.recording import channels
from fleet.recording.reader import RecordingError, read_recording, recover
from fleet.recording.writer import McapSink, Rotation, rotated_path

TELEMETRY = b'{"type":"telemetry","system_time_ms":1,"gps":{"lat":1.0,"lon":2.0,"alt":3.0}}'


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _write(sink: McapSink, count: int, clock: FakeClock | None = None, step: float = 0.0) -> None:
    spec = channels.channel_for("fleet/uav/7/telemetry")
    for i in range(count):
        if clock is not None:
            clock.now += step
        sink.write(spec, TELEMETRY, 1_000 + i, 1_000 + i)


def test_a_finished_file_has_schemas_channels_and_a_summary(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "a.mcap")
    _write(sink, 10)
    sink.close()
    with open(tmp_path / "a.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count == 10
        (schema,) = summary.schemas.values()
        assert (schema.name, schema.encoding) == ("Telemetry", "jsonschema")
        (channel,) = summary.channels.values()
        assert channel.message_encoding == "json"
        assert channel.metadata == {"pattern": "fleet/uav/*/telemetry"}
    recording = read_recording(tmp_path / "a.mcap")
    assert recording.counts() == {"fleet/uav/7/telemetry": 10}
    assert recording.truncated == {}


def test_an_unfinished_file_reads_back_up_to_its_last_flush(tmp_path: Path) -> None:
    # What a SIGKILLed recorder leaves: chunks flushed, no summary, no footer.
    clock = FakeClock()
    sink = McapSink(tmp_path / "live.mcap", flush_every_s=0.5, clock=clock)
    _write(sink, 50, clock, step=0.01)
    sink.flush()
    first_chunk_ends = (tmp_path / "live.mcap").stat().st_size
    _write(sink, 50, clock, step=0.01)
    sink.flush()
    shutil.copy(tmp_path / "live.mcap", tmp_path / "killed.mcap")
    recording = read_recording(tmp_path / "killed.mcap")
    assert len(recording.messages) == 100
    assert "killed.mcap" in next(iter(recording.truncated))
    # Cut inside the second chunk, as a kill during its write would: the first reads back.
    data = (tmp_path / "killed.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: first_chunk_ends + 40])
    assert len(read_recording(tmp_path / "cut.mcap").messages) == 50
    sink.close()


def test_chunks_are_lz4_compressed_and_read_by_mcap_s_own_reader(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "c.mcap")
    _write(sink, 1000)
    sink.close()
    size = (tmp_path / "c.mcap").stat().st_size
    # The same message a thousand times (each also has 16 bytes of index, uncompressed).
    assert size < 1000 * len(TELEMETRY) / 2, size
    with open(tmp_path / "c.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert {index.compression for index in summary.chunk_indexes} == {"lz4"}
        assert sum(1 for _ in reader.iter_messages()) == 1000


def test_recover_rewrites_an_unfinished_file_into_a_finished_one(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "live.mcap")
    _write(sink, 20)
    sink.flush()
    shutil.copy(tmp_path / "live.mcap", tmp_path / "killed.mcap")
    sink.close()
    recovered = recover(tmp_path / "killed.mcap", tmp_path / "fixed.mcap")
    assert len(recovered.messages) == 20
    with open(tmp_path / "fixed.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 20


def test_rotation_by_size_starts_complete_files(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "rec.mcap", Rotation(max_bytes=2_000))
    _write(sink, 100)
    sink.close()
    assert len(sink.files) > 2
    assert sink.files[0] == rotated_path(tmp_path / "rec.mcap", 1) == tmp_path / "rec-0001.mcap"
    for path in sink.files:
        with open(path, "rb") as f:
            make_reader(f).get_summary()  # each has its footer and summary
    assert len(read_recording(sink.files).messages) == 100


def test_rotation_by_time(tmp_path: Path) -> None:
    clock = FakeClock()
    sink = McapSink(tmp_path / "rec.mcap", Rotation(max_seconds=1.0), clock=clock)
    _write(sink, 30, clock, step=0.1)
    sink.close()
    assert len(sink.files) == 3


def test_a_file_that_is_not_mcap_is_refused_with_its_name(tmp_path: Path) -> None:
    bad = tmp_path / "notes.mcap"
    bad.write_bytes(b"hello, this is not a recording")
    with pytest.raises(RecordingError, match=r"notes\.mcap: not an MCAP recording"):
        read_recording(bad)
    (tmp_path / "short.mcap").write_bytes(b"\x89MC")
    with pytest.raises(RecordingError, match=r"short\.mcap: not an MCAP recording"):
        read_recording(tmp_path / "short.mcap")
    with pytest.raises(RecordingError, match="cannot open"):
        read_recording(tmp_path / "absent.mcap")
