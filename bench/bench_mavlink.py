"""`fleet mavlink`'s costs, each against a reference measured in the same run.

* Streams: one UAV-second of what the gateway sends (HEARTBEAT, SYS_STATUS,
  EXTENDED_SYS_STATE, GPS_RAW_INT, HOME_POSITION, MISSION_CURRENT once;
  GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD four times), built from a view and a telemetry
  packet and packed as MAVLink 2; the reference is packing as many ready-made
  HEARTBEATs, pymavlink's cheapest message. Gives the UAVs one core can stream; the same
  signed (MAVLink 2 signing, `--signing-key`) against unsigned.
* A flood: 50-frame datagrams from one station on loopback, drained by the endpoint
  once the station's share is spent (dropped unread); the reference is parsing the same
  datagrams with pymavlink, what every datagram would cost without the share.

Run: .venv/bin/python -m bench.bench_mavlink
No process is started; every socket is closed.
"""

from __future__ import annotations

import socket
import time

from pymavlink.dialects.v20 import common as mavlink2

from fleet.piccolo.telemetry import GpsBlock, RawBlock, SensorBlock, Telemetry
from ground.fleet_view import UavView
from ground.mavlink import endpoint as endpoint_module
from ground.mavlink import vehicle
from ground.mavlink.endpoint import Endpoint, InputDrops
from ground.mavlink.signing import StationKey, passphrase_secret, signing_encoder

SECONDS = 2000  #: UAV-seconds of streams built
DATAGRAMS = 2000
FRAMES_PER_DATAGRAM = 50

TELEMETRY = Telemetry(
    system_time_ms=1000,
    gps=GpsBlock(35.70, -120.79, 612.5, 20.0, -5.0, 0.0),
    sensor=SensorBlock(roll=10.0, pitch=-2.0, yaw=270.0, indicated_airspeed=21.0),
    raw=RawBlock(p=1.0, q=2.0, r=3.0, accel_x=0, accel_y=0, accel_z=-9.8),
)
VIEW = UavView(id=74, airspeed=21.0, ground_speed=20.6, heading=270.0, phase="flying")


def one_uav_second(sender: mavlink2.MAVLink) -> int:
    """Build and pack what the gateway sends for one UAV in one second; bytes packed."""
    size = 0
    messages: list[mavlink2.MAVLink_message | None] = [
        vehicle.heartbeat(VIEW, TELEMETRY),
        vehicle.sys_status(VIEW, TELEMETRY, 0),
        vehicle.extended_sys_state(TELEMETRY),
        vehicle.gps_raw(TELEMETRY, 1000),
        vehicle.home_position(35.70, -120.79),
        vehicle.mission_current(1, 3, False),
    ]
    for tick in range(4):
        messages += [
            vehicle.global_position(TELEMETRY, tick * 250),
            vehicle.attitude(TELEMETRY, tick * 250),
            vehicle.vfr_hud(VIEW, TELEMETRY),
        ]
    for message in messages:
        if message is not None:
            size += len(message.pack(sender))
    return size


MESSAGES = 18  #: in one UAV-second


def bench_streams() -> None:
    sender = mavlink2.MAVLink(None, 74, 1)
    started = time.process_time()
    for _ in range(SECONDS):
        one_uav_second(sender)
    ours = time.process_time() - started
    beat = vehicle.heartbeat(VIEW)
    started = time.process_time()
    for _ in range(SECONDS * MESSAGES):
        beat.pack(sender)
    reference = time.process_time() - started
    signer = signing_encoder(74, StationKey("bench", passphrase_secret("bench")))
    started = time.process_time()
    for _ in range(SECONDS):
        one_uav_second(signer)
    signed = time.process_time() - started
    per_uav_us = ours / SECONDS * 1e6
    print(
        f"streams: {per_uav_us:.0f} us of CPU (process time) per UAV-second ({MESSAGES} "
        f"messages, {one_uav_second(sender)} bytes), {ours / reference:.2f} x packing "
        f"{MESSAGES} ready HEARTBEATs ({reference / SECONDS * 1e6:.0f} us); one core streams "
        f"{1e6 / per_uav_us:.0f} UAVs (building and packing alone); signed: "
        f"{signed / SECONDS * 1e6:.0f} us, {signed / ours:.2f} x unsigned"
    )


def bench_flood() -> None:
    station = mavlink2.MAVLink(None, 250, 190)
    beat = bytes(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(station))
    datagram = beat * FRAMES_PER_DATAGRAM
    # No refill during the run: every datagram after the burst is over the share.
    endpoint_module.PEER_RATE_HZ = 0.0
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops())
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.connect(("127.0.0.1", endpoint.local_port))
            sock.send(datagram)
            endpoint.receive(0.5)  # the station is known
            for _ in range(20):  # spend its share
                sock.send(datagram)
            for _ in range(100):
                if not endpoint.receive(0.05):
                    break
            endpoint.drops = InputDrops()
            started = time.perf_counter()
            sent = 0
            # A few at a time, so the kernel's buffer never drops any.
            for _ in range(DATAGRAMS // 20):
                for _ in range(20):  # 50 KB: within the socket's receive buffer
                    sock.send(datagram)
                sent += 20
                deadline = time.monotonic() + 5.0
                while endpoint.drops.total() < sent and time.monotonic() < deadline:
                    endpoint.receive(0.01)
            ours = time.perf_counter() - started
    finally:
        endpoint.close()
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    started = time.perf_counter()
    for _ in range(DATAGRAMS):
        parser.parse_buffer(datagram)
    reference = time.perf_counter() - started
    print(
        f"flood: {DATAGRAMS / ours:.0f} datagrams/s dropped (wall clock, sending included) "
        f"({DATAGRAMS * FRAMES_PER_DATAGRAM / ours:.0f} frames/s), "
        f"{reference / ours:.1f} x faster than parsing them "
        f"({DATAGRAMS * FRAMES_PER_DATAGRAM / reference:.0f} frames/s)"
    )


if __name__ == "__main__":
    bench_streams()
    bench_flood()
