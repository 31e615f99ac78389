"""Read a recording back, finished or not, and repair an unfinished one.

`read_recording` streams the records in file order (`mcap.stream_reader.StreamReader`),
which needs no summary, so a file whose recorder was killed reads up to its last whole
record; where it ends early, `Recording.truncated` says so. A file that is not MCAP
raises RecordingError naming it.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader

from fleet.errors import FleetError
from fleet.recording.channels import ChannelSpec
from fleet.recording.writer import McapSink


class RecordingError(FleetError, ValueError):
    """A file that cannot be read as a recording; the message names it and says why."""


@dataclass(frozen=True)
class RecordedMessage:
    topic: str
    pattern: str
    schema_name: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes

    def value(self) -> Any:
        """The JSON payload decoded, or None if it is not JSON."""
        try:
            return msgspec.json.decode(self.data)
        except (msgspec.DecodeError, UnicodeDecodeError):
            return None


@dataclass
class RecordedChannel:
    topic: str
    pattern: str
    schema_name: str
    schema_encoding: str
    schema: bytes
    message_encoding: str


@dataclass
class Recording:
    """Every message of one or more files, in time order, and their channels."""

    paths: list[Path]
    messages: list[RecordedMessage] = field(default_factory=list)
    channels: dict[str, RecordedChannel] = field(default_factory=dict)
    #: Files that ended without a footer, and why reading stopped there.
    truncated: dict[str, str] = field(default_factory=dict)

    def counts(self) -> Counter[str]:
        """Messages per topic."""
        return Counter(m.topic for m in self.messages)

    def spec(self, topic: str) -> ChannelSpec:
        channel = self.channels[topic]
        return ChannelSpec(topic, channel.schema_name, channel.schema, channel.pattern)


def read_recording(paths: Path | Iterable[Path]) -> Recording:
    """Every message of `paths` (a file or rotated files), sorted by log time."""
    files = [paths] if isinstance(paths, Path) else list(paths)
    recording = Recording(files)
    for path in files:
        _read_file(path, recording)
    recording.messages.sort(key=lambda m: m.log_time_ns)
    return recording


def _read_file(path: Path, recording: Recording) -> None:
    try:
        stream = open(path, "rb")  # noqa: SIM115  # closed below
    except OSError as error:
        raise RecordingError(f"{path}: cannot open: {error.strerror}") from error
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    finished = False
    with stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                    _add_channel(recording, record, schemas.get(record.schema_id))
                elif isinstance(record, Message):
                    _add_message(recording, path, record, channels)
                elif isinstance(record, Footer):
                    finished = True
        except (McapError, EOFError, ValueError, KeyError, struct.error) as error:
            if not recording.messages and not channels:
                raise RecordingError(f"{path}: not an MCAP recording ({_why(error)})") from error
            recording.truncated[str(path)] = _why(error)
            return
    if not finished:
        recording.truncated[str(path)] = "no footer"


def _why(error: BaseException) -> str:
    return str(error) or type(error).__name__


def _add_channel(recording: Recording, channel: Channel, schema: Schema | None) -> None:
    recording.channels.setdefault(
        channel.topic,
        RecordedChannel(
            topic=channel.topic,
            pattern=channel.metadata.get("pattern", channel.topic),
            schema_name=schema.name if schema else "",
            schema_encoding=schema.encoding if schema else "",
            schema=schema.data if schema else b"",
            message_encoding=channel.message_encoding,
        ),
    )


def _add_message(
    recording: Recording, path: Path, message: Message, channels: dict[int, Channel]
) -> None:
    channel = channels.get(message.channel_id)
    if channel is None:
        raise RecordingError(f"{path}: message on unknown channel {message.channel_id}")
    known = recording.channels[channel.topic]
    recording.messages.append(
        RecordedMessage(
            topic=channel.topic,
            pattern=known.pattern,
            schema_name=known.schema_name,
            log_time_ns=message.log_time,
            publish_time_ns=message.publish_time,
            data=message.data,
        )
    )


def recover(path: Path, out: Path) -> Recording:
    """Rewrite what `path` holds into a finished file `out` (summary, footer)."""
    recording = read_recording(path)
    sink = McapSink(out)
    try:
        for message in recording.messages:
            sink.write(
                recording.spec(message.topic),
                message.data,
                message.log_time_ns,
                message.publish_time_ns,
            )
    finally:
        sink.close()
    return recording
