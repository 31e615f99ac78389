"""`fleet decode FILE|-`: a captured Piccolo link byte stream, one JSON object a line.

A diagnostic for a user with a serial capture: every decoded packet is printed with its
stream header and its decoded autopilot or planning-protocol message (or the raw bytes
of an unknown type); the last line holds the drop counters. Garbage is counted, never
fatal: the exit code is 0 whatever the stream holds; 2 if the capture cannot be read.
Runnable on its own as ``python -m fleet.tools.decode_command``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import IO, Any, TextIO

import msgspec

from fleet.mission.messages import MissionAbort, MissionTargets, OpmCommand, StatusText, UavResult
from fleet.payload.link import AutopilotEvent, LinkEvent, PiccoloLink, StreamHeader
from fleet.payload.protocol import UnknownPlanningMessage
from fleet.piccolo.autopilot_messages import UnknownAutopilotMessage
from fleet.transport.cli import ExitCode, fail
from fleet.transport.command import LocalCommand, add_command, options_from, run_standalone

CHUNK = 65536

_PLANNING_KINDS: dict[type, str] = {
    OpmCommand: "opm",
    StatusText: "status",
    MissionTargets: "targets",
    UavResult: "uav_result",
    MissionAbort: "abort",
}


def configure_parser(parser: argparse.ArgumentParser) -> None:
    """Add the `fleet decode` arguments to `parser`."""
    parser.add_argument("capture", help="capture file, or - for standard input")


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register the `decode` subcommand."""
    add_command(
        subparsers,
        "decode",
        DECODE,
        help="decode a captured Piccolo link byte stream to JSON lines",
        doc=__doc__,
        configure=configure_parser,
    )


def _header(header: StreamHeader) -> dict[str, int]:
    return {
        "source": header.source,
        "destination": header.destination,
        "stream": header.stream,
        "sequence": header.sequence,
        "acknowledge": header.acknowledge,
    }


def event_record(event: LinkEvent) -> dict[str, Any]:
    """One JSON-ready record: the stream header, the message kind, its fields."""
    record: dict[str, Any] = {"header": _header(event.header)}
    if isinstance(event, AutopilotEvent):
        message = event.message
        record["layer"] = "autopilot"
        if isinstance(message, UnknownAutopilotMessage):
            record["kind"] = "unknown"
            record["packet_type"] = message.packet_type
            record["raw"] = message.data.hex()
            if message.error:
                record["error"] = message.error
            return record
        fields = msgspec.to_builtins(message)
        record["kind"] = fields.pop("type")
        record["message"] = fields
        return record
    envelope = event.envelope
    record["layer"] = "planning"
    record["planning"] = {"source": envelope.source, "destination": envelope.destination}
    planning = envelope.message
    if isinstance(planning, UnknownPlanningMessage):
        record["kind"] = "unknown"
        record["packet_type"] = planning.type
        record["user"] = planning.user
        record["raw"] = planning.body.hex()
        return record
    record["kind"] = _PLANNING_KINDS[type(planning)]
    record["message"] = msgspec.to_builtins(planning)
    return record


def decode_stream(source: IO[bytes]) -> Iterator[dict[str, Any]]:
    """Records for every packet in `source`, then one `{"drops": ...}` record."""
    link = PiccoloLink(local_address=0)
    while chunk := source.read(CHUNK):
        for event in link.feed(chunk):
            yield event_record(event)
    link.planning_decoder.reassembler.expire(float("inf"))
    yield {"drops": link.drop_counters(), "packets": link.stream_decoder.packets}


@dataclass(frozen=True, kw_only=True)
class DecodeOptions:
    #: A capture file, or - for standard input.
    capture: str


def run(options: DecodeOptions, out: TextIO) -> int:
    """Print the records of the capture (a path, or - for stdin)."""
    try:
        if options.capture == "-":
            _write_records(sys.stdin.buffer, out)
        else:
            with open(options.capture, "rb") as capture:
                _write_records(capture, out)
    except OSError as error:
        return fail("fleet decode", f"cannot read {options.capture}: {error.strerror}")
    return ExitCode.OK


def _write_records(source: IO[bytes], out: TextIO) -> None:
    encoder = msgspec.json.Encoder()
    for record in decode_stream(source):
        out.write(encoder.encode(record).decode() + "\n")
    out.flush()


DECODE = LocalCommand(options_from(DecodeOptions), run)


def main(argv: Sequence[str] | None = None) -> int:
    return run_standalone("fleet decode", __doc__ or "", configure_parser, DECODE, argv)


if __name__ == "__main__":
    sys.exit(main())
