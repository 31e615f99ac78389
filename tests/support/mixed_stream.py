"""A realistic mixed Piccolo link byte stream, for the decoder benchmark and tests.

Telemetry at 20 Hz, a TRACK report every 10 s, waypoint echoes, planning-protocol
packets on the payload stream (status text, a targets message, results), and a given
fraction of stream packets corrupted by one flipped bit.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from fleet.mission.messages import MISSION_MANAGER, MissionTargets, StatusText, Target, UavResult
from fleet.payload.link import PiccoloLink
from fleet.payload.protocol import encode_message
from fleet.piccolo.stream_packet import ALL_OPERATOR_INTERFACES, BROADCAST_AVIONICS, MAX_PACKET
from fleet.piccolo.telemetry import GpsBlock, SensorBlock, Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint


@dataclass(frozen=True)
class MixedStream:
    data: bytes
    packets: int  #: stream packets written
    corrupted: int  #: stream packets with a flipped bit
    messages: int  #: autopilot and planning messages in the uncorrupted packets' streams


def _telemetry(t: float) -> Telemetry:
    heading = (t * 3.0) % 360.0
    return Telemetry(
        system_time_ms=round(t * 1000),
        gps=GpsBlock(
            lat=42.36 + 0.001 * math.sin(t / 30),
            lon=-71.09 + 0.001 * math.cos(t / 30),
            alt=150.0,
            vel_north=22.0 * math.cos(math.radians(heading)),
            vel_east=22.0 * math.sin(math.radians(heading)),
            vel_down=0.0,
        ),
        sensor=SensorBlock(roll=10.0, pitch=2.0, yaw=heading, indicated_airspeed=22.0),
    )


def mixed_stream(seconds: float, corrupt_fraction: float = 0.01, seed: int = 1) -> MixedStream:
    rng = random.Random(seed)
    link = PiccoloLink(local_address=112)
    packets: list[bytes] = []
    messages = 0
    steps = int(seconds * 20)
    for step in range(steps):
        t = step / 20
        packets.append(link.encode_autopilot(_telemetry(t), ALL_OPERATOR_INTERFACES))
        messages += 1
        if step % 200 == 0:
            packets.append(link.encode_autopilot(Track(step // 200 % 4), ALL_OPERATOR_INTERFACES))
            wp = Waypoint(index=step // 200 % 100, next_index=0, lat=42.3, lon=-71.1, alt=120.0)
            packets.append(link.encode_autopilot(wp, ALL_OPERATOR_INTERFACES))
            messages += 2
        if step % 20 == 0:
            status = StatusText(f"mission 7 waiting; tracking waypoint {step % 4}")
            payload = encode_message(status, 112, MISSION_MANAGER)
            packets.append(link.encode_payload(payload, ALL_OPERATOR_INTERFACES))
            messages += 1
        if step % 100 == 50:
            targets = MissionTargets(
                mission=step,
                team=(74, 112),
                targets=tuple(Target(42.3 + i / 100, -71.1, 100.0) for i in range(12)),
            )
            result = UavResult(mission=step, uav=112, times=tuple(60.0 + i for i in range(12)))
            for message in (targets, result):
                payload = encode_message(message, 112, BROADCAST_AVIONICS, seq=step % 65536)
                packets.append(link.encode_payload(payload, BROADCAST_AVIONICS))
                messages += 1
    # encode_* may return several stream packets at once: split them back apart.
    stream_packets = [p for chunk in packets for p in _split(chunk)]
    corrupted = 0
    out = bytearray()
    for packet in stream_packets:
        if rng.random() < corrupt_fraction:
            flipped = bytearray(packet)
            bit = rng.randrange(len(flipped) * 8)
            flipped[bit // 8] ^= 1 << (bit % 8)
            packet = bytes(flipped)
            corrupted += 1
        out += packet
    return MixedStream(bytes(out), len(stream_packets), corrupted, messages)


def _split(chunk: bytes) -> list[bytes]:
    parts = []
    position = 0
    while position < len(chunk):
        size = 16 + chunk[position + 12]
        assert size <= MAX_PACKET
        parts.append(chunk[position : position + size])
        position += size
    return parts
