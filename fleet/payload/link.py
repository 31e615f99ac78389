"""One end of a Piccolo serial link, pure: bytes in, typed events out, and back.

Stacks the stream-packet decoder, the autopilot packet decoder (autopilot stream) and
the planning-protocol decoder (payload stream); other streams' bytes wait in bounded
queues. No I/O: the onboard adapter, the simulator and `fleet decode` feed it the bytes
they read and write what it encodes.

Sequence and acknowledge numbers (docs/protocol.md §1, ASSUMPTION): each stream's
sequence number is the cumulative count of data bytes sent on it, including the
packet's own, modulo 2^16; the acknowledge number echoes the last sequence number
received from the peer on that stream. Received numbers are recorded, never enforced:
a peer that sends zeros is accepted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fleet.payload.protocol import Envelope, PlanningDecoder
from fleet.piccolo.autopilot_messages import (
    AutopilotMessage,
    decode_autopilot_message,
    encode_autopilot_message,
)
from fleet.piccolo.autopilot_packet import AutopilotPacketDecoder
from fleet.piccolo.decoder import Decoder
from fleet.piccolo.stream_packet import (
    MAX_DATA,
    STREAM_AUTOPILOT,
    STREAM_PAYLOAD,
    StreamDecoder,
    StreamPacket,
    encode_stream_packet,
)
from fleet.piccolo.stream_queue import StreamQueue


@dataclass(frozen=True, slots=True)
class StreamHeader:
    """The stream-packet header that completed a higher-level message."""

    source: int
    destination: int
    stream: int
    sequence: int
    acknowledge: int


@dataclass(frozen=True, slots=True)
class AutopilotEvent:
    header: StreamHeader
    message: AutopilotMessage


@dataclass(frozen=True, slots=True)
class PlanningEvent:
    header: StreamHeader
    envelope: Envelope


LinkEvent = AutopilotEvent | PlanningEvent


@dataclass
class PiccoloLink:
    """Decoder and encoder state of one serial port of a Piccolo link."""

    local_address: int
    stream_decoder: StreamDecoder = field(default_factory=StreamDecoder)
    autopilot_decoder: AutopilotPacketDecoder = field(default_factory=AutopilotPacketDecoder)
    planning_decoder: PlanningDecoder = field(default_factory=PlanningDecoder)
    queues: dict[int, StreamQueue] = field(default_factory=dict)
    _sent: dict[int, int] = field(default_factory=dict)
    _received: dict[int, int] = field(default_factory=dict)

    def queue(self, stream: int) -> StreamQueue:
        """The byte queue of `stream`; streams other than 3 and 6 stay opaque bytes here."""
        if stream not in self.queues:
            self.queues[stream] = StreamQueue()
        return self.queues[stream]

    def feed(self, chunk: bytes | bytearray | memoryview, now: float = 0.0) -> list[LinkEvent]:
        """Decode what `chunk` completes; `now` (seconds) ages planning-protocol segments."""
        events: list[LinkEvent] = []
        for packet in self.stream_decoder.feed(chunk):
            self._received[packet.stream] = packet.sequence
            header = StreamHeader(
                packet.source,
                packet.destination,
                packet.stream,
                packet.sequence,
                packet.acknowledge,
            )
            if packet.stream == STREAM_AUTOPILOT:
                for autopilot in self.autopilot_decoder.feed(packet.data):
                    events.append(AutopilotEvent(header, decode_autopilot_message(autopilot)))
            elif packet.stream == STREAM_PAYLOAD:
                events.extend(
                    PlanningEvent(header, envelope)
                    for envelope in self.planning_decoder.feed(packet.data, now)
                )
            else:
                self.queue(packet.stream).append(packet.data)
        return events

    def encode_stream(self, stream: int, data: bytes, destination: int) -> bytes:
        """Stream packets carrying `data`, split at 255 bytes a packet."""
        packets = []
        for start in range(0, len(data), MAX_DATA):
            piece = data[start : start + MAX_DATA]
            sequence = (self._sent.get(stream, 0) + len(piece)) & 0xFFFF
            self._sent[stream] = sequence
            packets.append(
                encode_stream_packet(
                    StreamPacket(
                        destination=destination,
                        source=self.local_address,
                        sequence=sequence,
                        acknowledge=self._received.get(stream, 0),
                        stream=stream,
                        data=piece,
                    )
                )
            )
        return b"".join(packets)

    def encode_autopilot(self, message: AutopilotMessage, destination: int) -> bytes:
        return self.encode_stream(STREAM_AUTOPILOT, encode_autopilot_message(message), destination)

    def encode_payload(self, planning_bytes: bytes, destination: int) -> bytes:
        """Stream-6 packets carrying already-encoded planning-protocol packets."""
        return self.encode_stream(STREAM_PAYLOAD, planning_bytes, destination)

    def drop_counters(self) -> dict[str, int]:
        """Everything dropped so far, by layer and reason."""
        decoders: dict[str, Decoder[object]] = {
            "stream": self.stream_decoder,
            "autopilot": self.autopilot_decoder,
            "planning": self.planning_decoder,
        }
        counters = {
            f"{layer}_{reason}": count
            for layer, decoder in decoders.items()
            for reason, count in decoder.drops.items()
        }
        counters["queue_overflow_bytes"] = sum(q.overflow_bytes for q in self.queues.values())
        return counters
