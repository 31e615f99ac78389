"""`fleet decode FILE|-`: a captured Piccolo link byte stream, one JSON object a line.

A diagnostic for a user with a serial capture: every decoded packet is printed with its
stream header and its decoded autopilot or planning-protocol message (or the raw bytes
of an unknown type); the last line holds the drop counters. Garbage is counted, never
fatal: the exit code is 0 whatever the stream holds.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from typing import IO, Any

import msgspec

from fleet.piccolo.autopilot_messages import UnknownAutopilotMessage
from fleet.planning.link import AutopilotEvent, LinkEvent, PiccoloLink, StreamHeader
from fleet.planning.protocol import UnknownPlanningMessage

CHUNK = 65536

_PLANNING_KINDS = {
    "OpmCommand": "opm",
    "StatusText": "status",
    "MissionTargets": "targets",
    "UavResult": "uav_result",
    "MissionAbort": "abort",
}


def add_parser(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "decode",
        help="decode a captured Piccolo link byte stream to JSON lines",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("capture", help="capture file, or - for standard input")
    parser.set_defaults(func=run)


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
    record["kind"] = _PLANNING_KINDS[type(planning).__name__]
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


def run(args: argparse.Namespace) -> int:
    encoder = msgspec.json.Encoder()
    out = sys.stdout.buffer
    try:
        if args.capture == "-":
            records = decode_stream(sys.stdin.buffer)
            for record in records:
                out.write(encoder.encode(record) + b"\n")
        else:
            with open(args.capture, "rb") as capture:
                for record in decode_stream(capture):
                    out.write(encoder.encode(record) + b"\n")
    except OSError as error:
        print(f"fleet decode: cannot read {args.capture}: {error.strerror}", file=sys.stderr)
        return 2
    out.flush()
    return 0
