"""An MCAP file that survives its writer being killed, with rotation by size or time.

MCAP's default writer buffers messages in compressed chunks of 1 MB and indexes them at
`finish()`: a writer killed before that leaves nothing readable (measured: all 1,000
messages lost). This one ends a chunk, LZ4-compressed, and flushes it to the file at
least every `flush_every_s`, so a SIGKILL loses at most that last interval (a chunk is
read back whole or not at all); `finish()` still writes the summary when the recorder
stops normally. `fleet record --recover` rewrites an unfinished file into a finished one
(`fleet.recording.reader.recover`).

Compression: the fleet's JSON compresses about 10x in half-second chunks. LZ4, not
zstd: `mcap` itself depends on `lz4`, so every reader of the project (and Foxglove)
reads it with nothing more installed.

With rotation, files are `OUT-0001.mcap`, `OUT-0002.mcap`, ...; each is a complete
recording with its own schemas and channels.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from mcap.writer import CompressionType, Writer

from fleet.recording.channels import MESSAGE_ENCODING, SCHEMA_ENCODING, ChannelSpec

log = logging.getLogger(__name__)

LIBRARY = "uav-fleet fleet record"
DEFAULT_FLUSH_EVERY_S = 0.5
#: A chunk ends at this size even before its flush (uncompressed bytes).
CHUNK_BYTES = 4 * 1024 * 1024


@dataclass(frozen=True)
class Rotation:
    """Start a new file past `max_bytes` written or `max_seconds` of recording (0: never)."""

    max_bytes: int = 0
    max_seconds: float = 0.0

    @property
    def enabled(self) -> bool:
        return self.max_bytes > 0 or self.max_seconds > 0


def rotated_path(path: Path, number: int) -> Path:
    return path.with_name(f"{path.stem}-{number:04d}{path.suffix or '.mcap'}")


@dataclass
class McapSink:
    """Writes channels' messages to `path` (or its rotated files). One thread only."""

    path: Path
    rotation: Rotation = field(default_factory=Rotation)
    flush_every_s: float = DEFAULT_FLUSH_EVERY_S
    clock: Callable[[], float] = time.monotonic
    files: list[Path] = field(default_factory=list)
    messages: int = 0
    _file: IO[bytes] | None = None
    _writer: Writer | None = None
    _channels: dict[str, int] = field(default_factory=dict)
    _schemas: dict[str, int] = field(default_factory=dict)
    _opened_at: float = 0.0
    _flushed_at: float = 0.0
    #: Bytes given since the last flush, still in the writer's chunk (for rotation by size).
    _pending: int = 0

    def open(self) -> None:
        """Start the (first) file now, so a path that cannot be written fails at once."""
        if self._writer is None:
            self._open_next()

    def write(self, spec: ChannelSpec, data: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        if self._writer is None or self._rotation_due():
            self._open_next()
        assert self._writer is not None
        channel = self._channel(spec)
        self._writer.add_message(
            channel, log_time=log_time_ns, data=data, publish_time=publish_time_ns
        )
        self.messages += 1
        self._pending += len(data)
        self.flush_if_due()

    def flush_if_due(self) -> None:
        if self._file is not None and self.clock() - self._flushed_at >= self.flush_every_s:
            self.flush()

    def flush(self) -> None:
        """End the chunk in progress and write it out (readable after a kill from now)."""
        if self._writer is not None:
            self._writer.flush()  # type: ignore[no-untyped-call]
            self._pending = 0
        if self._file is not None:
            self._file.flush()
            self._flushed_at = self.clock()

    def close(self) -> None:
        """Finish the current file (summary and footer). Idempotent."""
        if self._writer is not None:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._writer = None
        if self._file is not None:
            self._file.close()
            self._file = None

    def _rotation_due(self) -> bool:
        rotation = self.rotation
        if not rotation.enabled or self._file is None:
            return False
        if rotation.max_bytes and self._file.tell() + self._pending >= rotation.max_bytes:
            return True
        return bool(rotation.max_seconds and self.clock() - self._opened_at >= rotation.max_seconds)

    def _open_next(self) -> None:
        self.close()
        path = rotated_path(self.path, len(self.files) + 1) if self.rotation.enabled else self.path
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(path, "wb")  # noqa: SIM115  # closed in close()
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES, compression=CompressionType.LZ4)
        self._pending = 0
        self._writer.start(profile="", library=LIBRARY)
        self._channels.clear()
        self._schemas.clear()
        self.files.append(path)
        self._opened_at = self._flushed_at = self.clock()
        log.info("recording to %s", path)

    def _channel(self, spec: ChannelSpec) -> int:
        channel = self._channels.get(spec.topic)
        if channel is not None:
            return channel
        assert self._writer is not None
        schema = 0
        if spec.schema_name:
            schema = self._schemas.get(spec.schema_name, 0)
            if not schema:
                schema = self._writer.register_schema(
                    name=spec.schema_name, encoding=SCHEMA_ENCODING, data=spec.schema
                )
                self._schemas[spec.schema_name] = schema
        channel = self._writer.register_channel(
            topic=spec.topic,
            message_encoding=MESSAGE_ENCODING,
            schema_id=schema,
            metadata=spec.metadata,
        )
        self._channels[spec.topic] = channel
        return channel
