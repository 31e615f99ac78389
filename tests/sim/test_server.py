"""The simulated autopilot's link: bytes in, bytes out, in-process and over real ports.

In-process tests feed bytes straight into a `SimulatedAutopilot` (exact and fast). The
port tests run a `SimServer` on 127.0.0.1 (port 0) in a thread at a high speedup, or a
real `fleet sim` subprocess, and talk to it with pyserial (`socket://` and a pty), as the
onboard module does. Every server, thread, socket and process is closed or killed.
"""

from __future__ import annotations

import logging
import math
import os
import random
import select
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.geo.angles import wrap_pi
from fleet.geo.mercator import MercatorProjection
from fleet.payload.link import AutopilotEvent, PiccoloLink
from fleet.piccolo.autopilot_packet import encode_autopilot_packet
from fleet.piccolo.stream_packet import STREAM_AUTOPILOT, StreamPacket, encode_stream_packet
from fleet.piccolo.telemetry import Telemetry, decode_telemetry, encode_telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint, decode_waypoint, encode_waypoint
from fleet.sim.autopilot import (
    DEFAULT_TELEMETRY_HZ,
    STEP_MS,
    AutopilotSettings,
    ProgramConnection,
    SimulatedAutopilot,
)
from fleet.sim.command import main as sim_main
from fleet.sim.scenario import Scenario, shipped_scenario
from fleet.sim.server import Endpoints, SimServer

#: The address the test clients send from (an operator interface, like the onboard module).
CLIENT = 0xFFFE
#: A waypoint index no shipped scenario's flight plan uses.
UNUSED_WAYPOINT = 99
#: How long a port test waits for something before failing (wall seconds).
WAIT_S = 15.0

SINGLE = shipped_scenario("single_uav")
HEAD_ON = shipped_scenario("head_on")


def autopilot_for(
    scenario: Scenario, index: int = 0, telemetry_hz: float = DEFAULT_TELEMETRY_HZ
) -> SimulatedAutopilot:
    settings_ = AutopilotSettings(
        limits=scenario.limits, wind=scenario.wind, telemetry_hz=telemetry_hz
    )
    return SimulatedAutopilot(scenario.uavs[index], settings_)


def quantized(telemetry: Telemetry) -> Telemetry:
    """What a telemetry packet decodes to after the wire's rounding."""
    return decode_telemetry(encode_telemetry(telemetry))


def decode_output(link: PiccoloLink, data: bytes) -> list[AutopilotEvent]:
    events = link.feed(data)
    assert all(isinstance(e, AutopilotEvent) for e in events)
    return [e for e in events if isinstance(e, AutopilotEvent)]


# -- in-process: the autopilot alone ----------------------------------------------------


class Bench:
    """An autopilot with one program connection and a client link, in-process."""

    def __init__(self, autopilot: SimulatedAutopilot) -> None:
        self.autopilot = autopilot
        self.connection: ProgramConnection = autopilot.open_program("bench")
        self.client = PiccoloLink(local_address=CLIENT)

    def send(self, message: Waypoint | Track, destination: int | None = None) -> None:
        target = self.autopilot.piccolo_id if destination is None else destination
        self.autopilot.receive(self.connection, self.client.encode_autopilot(message, target))

    def events(self) -> list[AutopilotEvent]:
        return decode_output(self.client, self.connection.output.take())

    def step_until(self, condition: Callable[[], bool], seconds: float) -> None:
        for _ in range(round(seconds * 1000 / STEP_MS)):
            if condition():
                return
            self.autopilot.step()
        raise AssertionError(f"condition not met in {seconds} simulated seconds")


def local(autopilot: SimulatedAutopilot, lat: float, lon: float) -> tuple[float, float]:
    return autopilot.projection.to_xy(lat, lon)


def test_telemetry_carries_the_model_state_at_the_configured_rate() -> None:
    for rate, expected in ((1.0, 10), (20.0, 200)):
        bench = Bench(autopilot_for(SINGLE, telemetry_hz=rate))
        bench.autopilot.advance_to(10_000)
        telemetry = [e for e in bench.events() if isinstance(e.message, Telemetry)]
        assert len(telemetry) == expected
        assert all(e.header.source == 112 and e.header.destination == 0xFFFE for e in telemetry)
        last = telemetry[-1].message
        assert isinstance(last, Telemetry) and last.gps is not None and last.sensor is not None
        assert last == quantized(bench.autopilot.telemetry())
        # Simulated time in the system time and in GPS time of week.
        assert last.system_time_ms == bench.autopilot.time_ms
        assert last.gps.gps_time_of_week_ms == bench.autopilot.time_ms
        # Flying east at 22 m/s, level: 22 m/s of indicated airspeed at sea level only.
        assert last.gps.vel_east == pytest.approx(22.0)
        assert last.sensor.yaw == pytest.approx(90.0, abs=0.01)
        assert last.sensor.indicated_airspeed == pytest.approx(
            22.0 * math.sqrt(last.sensor.density_ratio), abs=0.02
        )


def test_track_is_reported_every_second_and_on_change() -> None:
    bench = Bench(autopilot_for(SINGLE))
    bench.autopilot.advance_to(3_500)
    tracks = [e.message for e in bench.events() if isinstance(e.message, Track)]
    assert tracks == [Track(0)] * 4


def test_waypoint_then_track_flies_to_it_then_on_to_its_next() -> None:
    bench = Bench(autopilot_for(SINGLE))
    autopilot = bench.autopilot
    autopilot.advance_to(2_000)
    bench.events()
    lat, lon = autopilot.projection.to_latlon(1500.0, 1200.0)
    sent = Waypoint(index=42, next_index=2, lat=lat, lon=lon, alt=650.0)
    bench.send(sent)
    (echo,) = bench.events()
    assert echo.message == decode_waypoint(encode_waypoint(sent))
    assert echo.header.destination == CLIENT
    bench.send(Track(42))
    (track_echo,) = bench.events()
    assert track_echo.message == Track(42)
    assert autopilot.tracked == 42

    target = local(autopilot, lat, lon)
    distances: list[float] = []

    def moved_on() -> bool:
        distances.append(math.hypot(autopilot.state.x - target[0], autopilot.state.y - target[1]))
        return autopilot.tracked != 42

    bench.step_until(moved_on, 200.0)
    assert autopilot.tracked == 2
    assert distances[-1] <= 60.0 < distances[-2]
    assert Track(2) in [e.message for e in bench.events()]
    # The altitude of the waypoint was commanded too.
    assert autopilot.state.alt > 600.0
    # Then on to waypoint 2: after a while the course points at it.
    wp2 = autopilot.plan.get(2)
    assert wp2 is not None
    x2, y2 = local(autopilot, wp2.lat, wp2.lon)
    autopilot.advance_to(autopilot.time_ms + 40_000)
    north, east = autopilot.state.ground_velocity()
    bearing = math.atan2(x2 - autopilot.state.x, y2 - autopilot.state.y)
    error = wrap_pi(math.atan2(east, north) - bearing)
    assert abs(math.degrees(error)) < 10.0


def test_refused_and_misaddressed_commands_change_nothing() -> None:
    bench = Bench(autopilot_for(SINGLE))
    autopilot = bench.autopilot
    autopilot.advance_to(1_000)
    bench.events()
    before = (autopilot.plan.waypoints(), autopilot.tracked)
    # TRACK to a waypoint that is not stored: answered with the waypoint still tracked.
    bench.send(Track(77))
    assert [e.message for e in bench.events()] == [Track(0)]
    # A waypoint for another Piccolo, and a broadcast one with an index past 99.
    bench.send(Waypoint(index=0, next_index=1, lat=35.0, lon=-120.0, alt=500.0), destination=999)
    bad = struct.pack(">iiBBhBBBBBB", 0, 0, 0, 0, 500, 0, 0, 150, 0, 0, 0)
    packet = encode_autopilot_packet(8, bad)
    autopilot.receive(bench.connection, bench.client.encode_stream(3, packet, 0xFFFF))
    assert bench.events() == []
    assert (autopilot.plan.waypoints(), autopilot.tracked) == before
    assert autopilot.counters["refused_tracks"] == 1
    assert autopilot.counters["refused_waypoints"] == 1
    assert autopilot.counters["not_addressed_to_us"] == 1


def test_a_waypoint_whose_next_is_missing_stays_tracked() -> None:
    bench = Bench(autopilot_for(SINGLE))
    autopilot = bench.autopilot
    lat, lon = autopilot.projection.to_latlon(600.0, 300.0)
    bench.send(Waypoint(index=50, next_index=51, lat=lat, lon=lon, alt=600.0))
    bench.send(Track(50))
    target = local(autopilot, lat, lon)
    bench.step_until(lambda: math.dist((autopilot.state.x, autopilot.state.y), target) < 60, 120)
    autopilot.advance_to(autopilot.time_ms + 60_000)
    assert autopilot.tracked == 50
    assert autopilot.counters["arrivals_without_next"] == 1
    # Storing the missing next lets it go on at the next pass.
    bench.send(Waypoint(index=51, next_index=0, lat=lat, lon=lon + 0.05, alt=600.0))
    bench.step_until(lambda: autopilot.tracked == 51, 120)


def dangerous_waypoint(autopilot: SimulatedAutopilot) -> Waypoint:
    """A valid WAYPOINT that would move the tracked waypoint far away if it got through."""
    lat, lon = autopilot.projection.to_latlon(-5000.0, 4000.0)
    return Waypoint(index=autopilot.tracked, next_index=1, lat=lat, lon=lon, alt=900.0)


def garbage_corpus(autopilot: SimulatedAutopilot, rng: random.Random) -> list[bytes]:
    """Invalid bytes of every kind, built around commands that would matter if accepted."""
    encoder = PiccoloLink(local_address=CLIENT)
    piccolo = autopilot.piccolo_id
    valid = encoder.encode_autopilot(dangerous_waypoint(autopilot), piccolo)
    track = encoder.encode_autopilot(Track(2), piccolo)

    def flipped(data: bytes, position: int) -> bytes:
        out = bytearray(data)
        out[position] ^= 0x10
        return bytes(out)

    bad_inner = bytearray(encode_autopilot_packet(10, bytes((2, 0))))
    bad_inner[-1] ^= 0xFF  # the autopilot packet's CRC, inside a valid stream packet
    return [
        rng.randbytes(400),
        flipped(valid, 5),  # header checksum fails
        flipped(valid, 20),  # CRC fails
        flipped(track, len(track) - 1),
        valid[:-3],  # truncated: its CRC can never match
        b"\x5a\xa5" * 30 + b"\xa0\x05" * 30,  # syncs without packets
        encode_stream_packet(
            StreamPacket(piccolo, CLIENT, 0, 0, STREAM_AUTOPILOT, bytes(bad_inner))
        ),
        encoder.encode_autopilot(dangerous_waypoint(autopilot), piccolo + 1),  # not ours
        rng.randbytes(2000),
    ]


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), when=st.lists(st.integers(0, 400), min_size=3, max_size=8))
def test_garbage_never_disturbs_the_aircraft(seed: int, when: list[int]) -> None:
    clean = Bench(autopilot_for(SINGLE))
    noisy = Bench(autopilot_for(SINGLE))
    rng = random.Random(seed)
    corpus = garbage_corpus(noisy.autopilot, rng)
    for count in range(500):
        if count in when:
            for chunk in corpus:
                # In random pieces: packets straddle reads, as on a serial line.
                cut = rng.randrange(len(chunk) + 1)
                noisy.autopilot.receive(noisy.connection, chunk[:cut])
                noisy.autopilot.receive(noisy.connection, chunk[cut:])
        clean.autopilot.step()
        noisy.autopilot.step()
        assert noisy.autopilot.state == clean.autopilot.state
        assert noisy.autopilot.tracked == clean.autopilot.tracked
    assert noisy.autopilot.plan.waypoints() == clean.autopilot.plan.waypoints()
    drops = noisy.autopilot.link_drops()
    assert drops["stream_skipped_bytes"] > 0
    assert drops["stream_bad_crc"] > 0
    assert drops["autopilot_bad_crc"] > 0
    # Afterwards the line still works.
    noisy.send(Track(2))
    assert Track(2) in [e.message for e in noisy.events()]


# -- over real ports ----------------------------------------------------------------------


@contextmanager
def running(
    autopilots: list[SimulatedAutopilot],
    speedup: float = 50.0,
    use_pty: bool = False,
    report_interval: float = 10.0,
) -> Iterator[tuple[SimServer, list[Endpoints]]]:
    """A SimServer on free 127.0.0.1 ports, run in a thread; stopped and closed after."""
    with SimServer(
        autopilots,
        program_port=0,
        payload_port=0,
        ground_port=0,
        speedup=speedup,
        use_pty=use_pty,
        report_interval=report_interval,
    ) as server:
        endpoints = server.open()
        thread = threading.Thread(target=server.run, name="sim-server", daemon=True)
        thread.start()
        try:
            yield server, endpoints
        finally:
            server.stop()
            thread.join(timeout=10.0)
            assert not thread.is_alive()


class Client:
    """A pyserial port speaking the Piccolo link, as the onboard module does."""

    def __init__(self, port: serial.SerialBase, piccolo_id: int) -> None:
        self.port = port
        self.piccolo_id = piccolo_id
        self.link = PiccoloLink(local_address=CLIENT)

    def send(self, message: Waypoint | Track) -> None:
        self.port.write(self.link.encode_autopilot(message, self.piccolo_id))

    def read_until(
        self, done: Callable[[AutopilotEvent], bool], timeout: float = WAIT_S
    ) -> list[AutopilotEvent]:
        """Events read up to and including the first for which `done` is true."""
        events: list[AutopilotEvent] = []
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for event in decode_output(self.link, self.port.read(4096)):
                events.append(event)
                if done(event):
                    return events
        raise AssertionError(f"nothing awaited within {timeout} s; read {len(events)} events")

    def telemetry(self, count: int) -> list[Telemetry]:
        seen: list[Telemetry] = []

        def enough(event: AutopilotEvent) -> bool:
            if isinstance(event.message, Telemetry):
                seen.append(event.message)
            return len(seen) >= count

        self.read_until(enough)
        return seen


def open_port(url: str) -> serial.SerialBase:
    """A pyserial port that keeps what is already waiting when it opens.

    pyserial's socket:// open() drains the socket until it is empty: that would throw
    away bytes the test expects, and against a simulator at --speedup 0 on a loaded
    machine the drain may never end.
    """
    port = serial.serial_for_url(url, timeout=0.05, do_not_open=True)
    port.reset_input_buffer = lambda: None  # type: ignore[method-assign]
    port.open()
    return port


@contextmanager
def connect(url: str, piccolo_id: int) -> Iterator[Client]:
    with open_port(url) as port:
        yield Client(port, piccolo_id)


def assert_matches_model(received: list[Telemetry], reference: SimulatedAutopilot) -> None:
    for telemetry in received:
        reference.advance_to(telemetry.system_time_ms)
        assert reference.time_ms == telemetry.system_time_ms
        assert telemetry == quantized(reference.telemetry())


def test_socket_client_reads_telemetry_matching_the_model() -> None:
    with running([autopilot_for(HEAD_ON, 0), autopilot_for(HEAD_ON, 1)]) as (_, endpoints):
        assert [e.piccolo_id for e in endpoints] == [74, 112]
        assert endpoints[0].line().startswith("uav 74 program=socket://127.0.0.1:")
        with connect(endpoints[1].program, 112) as client:
            received = client.telemetry(20)
    assert_matches_model(received, autopilot_for(HEAD_ON, 1))
    # Independently of the model code: the positions follow from the velocities (over
    # half a second, so that the wire's 1-mas rounding, ~3 cm, stays small).
    projection = MercatorProjection(HEAD_ON.uavs[1].lat, HEAD_ON.uavs[1].lon)
    for a, b in zip(received, received[10:], strict=False):
        assert a.gps is not None and b.gps is not None
        dt = (b.system_time_ms - a.system_time_ms) / 1000.0
        xa, ya = projection.to_xy(a.gps.lat, a.gps.lon)
        xb, yb = projection.to_xy(b.gps.lat, b.gps.lon)
        assert (xb - xa) / dt == pytest.approx((a.gps.vel_east + b.gps.vel_east) / 2, abs=0.1)
        assert (yb - ya) / dt == pytest.approx((a.gps.vel_north + b.gps.vel_north) / 2, abs=0.1)
    assert received[0].gps is not None
    assert received[0].gps.vel_east == pytest.approx(-22.0)  # 112 flies west


def test_waypoint_then_track_over_the_link() -> None:
    uav = SINGLE.uavs[0]
    projection = MercatorProjection(uav.lat, uav.lon)
    with (
        running([autopilot_for(SINGLE)], speedup=100.0) as (_, endpoints),
        connect(endpoints[0].program, 112) as client,
    ):
        (now,) = client.telemetry(1)
        assert now.gps is not None
        x, y = projection.to_xy(now.gps.lat, now.gps.lon)
        lat, lon = projection.to_latlon(x + 800.0, y - 1000.0)
        sent = Waypoint(index=10, next_index=1, lat=lat, lon=lon, alt=600.0)
        client.send(sent)
        client.read_until(lambda e: e.message == decode_waypoint(encode_waypoint(sent)))
        client.send(Track(10))
        client.read_until(lambda e: e.message == Track(10))
        target = projection.to_xy(lat, lon)
        approach = client.read_until(lambda e: e.message == Track(1), timeout=WAIT_S)
        positions = [
            projection.to_xy(e.message.gps.lat, e.message.gps.lon)
            for e in approach
            if isinstance(e.message, Telemetry) and e.message.gps is not None
        ]
        # The last telemetry before the switch is within the acceptance radius (plus
        # the ~1 m flown between it and the switching step).
        assert math.dist(positions[-1], target) <= 60.0 + 2.0
        assert min(math.dist(p, target) for p in positions[:-3]) > 60.0
        after = client.telemetry(100)  # 5 s simulated
    corner = SINGLE.uavs[0].waypoints()[1]
    corner_xy = projection.to_xy(corner.lat, corner.lon)
    distances = [
        math.dist(projection.to_xy(t.gps.lat, t.gps.lon), corner_xy) for t in after if t.gps
    ]
    assert distances[-1] < distances[0]


def test_garbage_on_the_port_leaves_the_aircraft_undisturbed(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING, logger="fleet.sim.server")
    autopilot = autopilot_for(SINGLE)
    rng = random.Random(7)
    corpus = garbage_corpus(autopilot_for(SINGLE), rng)
    received: list[Telemetry] = []
    with (
        running([autopilot], speedup=50.0, report_interval=0.05) as (_, endpoints),
        connect(endpoints[0].program, 112) as client,
    ):
        for chunk in corpus * 3:
            client.port.write(chunk)
            received.extend(client.telemetry(3))
        # The telemetry read may be older than the last chunk: before stopping the
        # server, see it has read everything written, by the echo of a waypoint written
        # after it (never tracked: the flight is not changed).
        lat, lon = autopilot.projection.to_latlon(0.0, 0.0)
        barrier = Waypoint(
            index=UNUSED_WAYPOINT, next_index=UNUSED_WAYPOINT, lat=lat, lon=lon, alt=600.0
        )
        client.send(barrier)
        echo = decode_waypoint(encode_waypoint(barrier))
        received.extend(
            e.message
            for e in client.read_until(lambda e: e.message == echo)
            if isinstance(e.message, Telemetry)
        )
    # After stop(): the server thread has ended, its counters are safe to read.
    assert_matches_model(received, autopilot_for(SINGLE))
    drops = autopilot.link_drops()
    assert drops["stream_skipped_bytes"] > 3 * 2400
    assert drops["stream_bad_crc"] >= 3
    assert drops["autopilot_bad_crc"] >= 3
    assert autopilot.counters["not_addressed_to_us"] == 3
    assert "uav 112: program port dropped so far" in caplog.text


# e2e though it starts no process: the flat-out simulation and its replay by the reference
# model take 25 s to minutes of CPU on a shared machine, too slow for the fast tier.
@pytest.mark.e2e
def test_speedup_zero_runs_as_fast_as_it_can_and_stays_exact() -> None:
    with (
        running([autopilot_for(SINGLE)], speedup=0.0) as (server, endpoints),
        connect(endpoints[0].program, 112) as client,
    ):
        received = client.telemetry(40)
    assert server.time_ms >= received[-1].system_time_ms
    assert_matches_model(received, autopilot_for(SINGLE))


def test_aircraft_get_consecutive_ports_from_the_base_ports() -> None:
    rng = random.Random()
    for _ in range(5):  # a random base may collide with a port in use: try another
        base = rng.randrange(20_000, 60_000, 10)
        server = SimServer(
            [autopilot_for(HEAD_ON, 0), autopilot_for(HEAD_ON, 1)],
            program_port=base,
            payload_port=base + 2,
            ground_port=base + 4,
        )
        with server:
            try:
                endpoints = server.open()
            except OSError:
                continue
            assert [e.line() for e in endpoints] == [
                f"uav {i} program=socket://127.0.0.1:{base + k} "
                f"payload=socket://127.0.0.1:{base + 2 + k} "
                f"ground=socket://127.0.0.1:{base + 4 + k}"
                for k, i in enumerate((74, 112))
            ]
            return
    pytest.skip("no free block of ports found")


def test_a_client_that_reconnects_is_served_again_and_learns_the_track() -> None:
    with running([autopilot_for(SINGLE)], speedup=20.0) as (_, endpoints):
        with connect(endpoints[0].program, 112) as client:
            first = client.telemetry(3)
        with connect(endpoints[0].program, 112) as client:
            events = client.read_until(lambda e: isinstance(e.message, Track))
            again = [e.message for e in events if isinstance(e.message, Telemetry)]
            # A late client hears the tracked waypoint within a simulated second.
            assert len(again) <= 21
            later = client.telemetry(2)
    assert later[-1].system_time_ms > first[-1].system_time_ms


def test_payload_pipe_carries_bytes_both_ways() -> None:
    with running([autopilot_for(SINGLE)], speedup=20.0) as (_, endpoints):
        (endpoint,) = endpoints
        with open_port(endpoint.payload) as onboard:
            early = b"\xb5 sent before the ground connected"
            onboard.write(early)
            with open_port(endpoint.ground) as ground:
                assert read_exactly(ground, len(early)) == early
                up = bytes(range(256)) * 8
                ground.write(up)
                assert read_exactly(onboard, len(up)) == up
                down = os.urandom(3000)
                onboard.write(down)
                assert read_exactly(ground, len(down)) == down


def read_exactly(port: serial.SerialBase, count: int) -> bytes:
    data = b""
    deadline = time.monotonic() + WAIT_S
    while len(data) < count and time.monotonic() < deadline:
        data += port.read(count - len(data))
    return data


def test_pty_client_reads_telemetry_and_commands_the_autopilot() -> None:
    with running([autopilot_for(SINGLE)], speedup=20.0, use_pty=True) as (_, endpoints):
        (endpoint,) = endpoints
        assert endpoint.program.startswith("/dev/")
        assert endpoint.ground.startswith("socket://")
        with serial.Serial(endpoint.program, timeout=0.05) as port:
            port.reset_input_buffer()
            client = Client(port, 112)
            received = client.telemetry(5)
            client.send(Track(2))
            client.read_until(lambda e: e.message == Track(2))
        with (
            serial.Serial(endpoint.payload, timeout=0.05) as onboard,
            serial.serial_for_url(endpoint.ground, timeout=0.05) as ground,
        ):
            onboard.write(b"payload over a pty")
            assert read_exactly(ground, 18) == b"payload over a pty"
    assert_matches_model(received, autopilot_for(SINGLE))


# -- the `fleet sim` command ---------------------------------------------------------------


def read_until_ready(process: subprocess.Popen[bytes]) -> list[str]:
    """The lines `fleet sim` prints up to `ready`, read from the raw pipe (a buffered
    reader would hide lines it has already read from `select`)."""
    assert process.stdout is not None
    fd = process.stdout.fileno()
    data = b""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        readable, _, _ = select.select([fd], [], [], 0.1)
        if readable:
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            data += chunk
            lines = data.decode().splitlines()
            if "ready" in lines:
                return lines
    raise AssertionError(f"no 'ready' line; got {data!r}")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
@pytest.mark.e2e
def test_fleet_sim_subprocess_serves_every_uav_and_exits_cleanly(sig: signal.Signals) -> None:
    command = [sys.executable, "-m", "fleet.sim.command", "head_on", "--speedup", "20"]
    command += ["--program-port", "0", "--payload-port", "0", "--ground-port", "0"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lines = read_until_ready(process)
        assert len(lines) == 3
        fields = [dict(part.split("=", 1) for part in line.split()[2:]) for line in lines[:2]]
        assert [line.split()[:2] for line in lines[:2]] == [["uav", "74"], ["uav", "112"]]
        with connect(fields[0]["program"], 74) as client:
            (telemetry,) = client.telemetry(1)
        assert telemetry.gps is not None and telemetry.gps.vel_east == pytest.approx(22.0)
        process.send_signal(sig)
        _, stderr = process.communicate(timeout=WAIT_S)
        assert process.returncode == 0, stderr.decode()
        assert b"stopping" in stderr
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def test_fleet_sim_refuses_an_unknown_scenario_or_uav(capsys: pytest.CaptureFixture[str]) -> None:
    assert sim_main(["nowhere"]) == 2
    assert "no shipped scenario 'nowhere'" in capsys.readouterr().err
    assert sim_main(["head_on", "--uav", "5"]) == 2
    assert "no uav with id 5" in capsys.readouterr().err


def test_fleet_sim_reports_a_port_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        status = sim_main(["single_uav", "--program-port", str(port), "--payload-port", "0"])
    assert status == 1
    assert f"cannot listen for the program listener on 127.0.0.1:{port}" in capsys.readouterr().err
