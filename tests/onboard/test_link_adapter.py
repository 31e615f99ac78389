"""The link adapter's loop over in-memory links: bytes in become events, commands become
bytes out, garbage is counted, and a dropped port is reported without stopping the loop."""

from __future__ import annotations

import logging
import queue
import socket
from collections.abc import Iterator
from typing import TypeVar

import pytest

from fleet.mission.messages import MISSION_MANAGER, StatusText
from fleet.payload.link import AutopilotEvent, LinkEvent, PiccoloLink, PlanningEvent
from fleet.payload.protocol import encode_message
from fleet.piccolo.stream_packet import ALL_GROUND_STATIONS, ALL_OPERATOR_INTERFACES
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.piccolo.track import Track
from fleet.transport.memory import MemoryLink, memory_link_pair
from fleet.transport.serial_port import SerialLink
from onboard.link_adapter import ONBOARD_ADDRESS, LinkAdapter
from tests.support.waiting import wait_until

UAV = 112
TELEMETRY = Telemetry(system_time_ms=1000, gps=GpsBlock(35.72, -120.76, 600.0, 0.0, 22.0, 0.0))


class Harness:
    def __init__(self) -> None:
        self.events: queue.SimpleQueue[LinkEvent] = queue.SimpleQueue()
        program, self.program = memory_link_pair("program")
        payload, self.payload = memory_link_pair("payload")
        self.adapter = LinkAdapter(UAV, program, payload, sink=self.events.put, poll_interval=0.002)
        #: The autopilot's side of each port.
        self.autopilot = PiccoloLink(UAV)
        self.ground = PiccoloLink(ALL_GROUND_STATIONS)

    def next_event(self) -> LinkEvent:
        return self.events.get(timeout=5.0)

    def received(self, link: MemoryLink, codec: PiccoloLink) -> list[LinkEvent]:
        found: list[LinkEvent] = []

        def some() -> bool:
            found.extend(codec.feed(link.read(0.0)))
            return bool(found)

        wait_until(some, 5.0, f"bytes on the {link.name} port")
        return found


@pytest.fixture
def harness() -> Iterator[Harness]:
    h = Harness()
    h.adapter.start()
    try:
        yield h
    finally:
        h.adapter.stop()


def test_telemetry_bytes_become_an_event(harness: Harness) -> None:
    harness.program.write(harness.autopilot.encode_autopilot(TELEMETRY, ONBOARD_ADDRESS), 0.0)
    event = harness.next_event()
    assert isinstance(event, AutopilotEvent) and event.message == TELEMETRY


def test_planning_bytes_on_the_payload_port_become_an_event(harness: Harness) -> None:
    status = StatusText("hello")
    planning = encode_message(status, MISSION_MANAGER, UAV)
    harness.payload.write(harness.ground.encode_payload(planning, ALL_OPERATOR_INTERFACES), 0.0)
    event = harness.next_event()
    assert isinstance(event, PlanningEvent) and event.envelope.message == status


def test_commands_go_out_on_their_ports(harness: Harness) -> None:
    harness.adapter.send_autopilot(Track(90))
    (event,) = harness.received(harness.program, harness.autopilot)
    assert isinstance(event, AutopilotEvent) and event.message == Track(90)
    assert event.header.destination == UAV
    harness.adapter.send_payload(encode_message(StatusText("up"), UAV, MISSION_MANAGER), 0)
    (sent,) = harness.received(harness.payload, harness.ground)
    assert isinstance(sent, PlanningEvent) and sent.envelope.message == StatusText("up")


def test_garbage_is_counted_and_the_loop_keeps_serving(harness: Harness) -> None:
    harness.program.write(b"\x00garbage\xff" * 10, 0.0)
    harness.program.write(harness.autopilot.encode_autopilot(TELEMETRY, ONBOARD_ADDRESS), 0.0)
    event = harness.next_event()
    assert isinstance(event, AutopilotEvent) and event.message == TELEMETRY
    health = harness.adapter.health(0.0)
    assert sum(health.drops.values()) > 0 and health.packets == 1


def test_a_dropped_port_is_reported_and_nothing_is_sent(
    harness: Harness, caplog: pytest.LogCaptureFixture
) -> None:
    harness.adapter.note_telemetry(10.0)
    assert harness.adapter.health(12.5).telemetry_age_s == 2.5
    harness.program.disconnect()
    health = harness.adapter.health(0.0)
    assert not health.program_up and health.payload_up
    with caplog.at_level(logging.WARNING, logger="onboard.link_adapter"):
        harness.adapter.send_autopilot(Track(1))
        wait_until(lambda: "program port down: Track not sent" in caplog.text, 5.0, "the loss")
    harness.program.reconnect()
    # Sent while down: lost, not queued for later; the next command goes through.
    harness.adapter.send_autopilot(Track(2))
    events = harness.received(harness.program, harness.autopilot)
    assert [e.message for e in events if isinstance(e, AutopilotEvent)] == [Track(2)]


class CountingLink(SerialLink):
    """A socket:// port that counts its reads."""

    reads: int = 0

    def read(self, now: float) -> bytes:
        self.reads += 1
        return super().read(now)


L = TypeVar("L", bound=SerialLink)


def socket_ports(link_type: type[L]) -> tuple[list[socket.socket], tuple[L, L]]:
    """Two listening sockets (the simulator's side) and the program and payload links
    that will dial them."""
    servers = [socket.create_server(("127.0.0.1", 0)) for _ in range(2)]
    program, payload = (
        link_type(name, f"socket://127.0.0.1:{server.getsockname()[1]}")
        for name, server in zip(("program", "payload"), servers, strict=True)
    )
    return servers, (program, payload)


def test_only_the_readable_port_is_read_and_every_packet_arrives_in_order() -> None:
    """Over sockets (as from the simulator) the loop reads only the ports its select
    found readable: packets on the program port all arrive, in order, and the
    idle payload port is not read for each of them."""
    servers, (program, payload) = socket_ports(CountingLink)
    events: queue.SimpleQueue[LinkEvent] = queue.SimpleQueue()
    adapter = LinkAdapter(UAV, program, payload, sink=events.put)
    adapter.start()
    try:
        program_peer, _ = servers[0].accept()
        payload_peer, _ = servers[1].accept()
        autopilot = PiccoloLink(UAV)
        with program_peer, payload_peer:
            for n in range(20):
                sent = Telemetry(system_time_ms=n, gps=TELEMETRY.gps)
                program_peer.sendall(autopilot.encode_autopilot(sent, ONBOARD_ADDRESS))
                event = events.get(timeout=5.0)
                assert isinstance(event, AutopilotEvent) and event.message == sent
            assert payload.reads <= 2  # at the start only, not once per packet
            payload_peer.sendall(
                PiccoloLink(ALL_GROUND_STATIONS).encode_payload(
                    encode_message(StatusText("hi"), MISSION_MANAGER, UAV), ONBOARD_ADDRESS
                )
            )
            event = events.get(timeout=5.0)
            assert isinstance(event, PlanningEvent)
    finally:
        adapter.stop()
        for server in servers:
            server.close()


def test_a_socket_port_dropped_and_reopened_is_waited_on_again() -> None:
    """The loop waits on the ports' descriptors registered once: a socket port whose peer
    hung up is reopened (often on the same descriptor number), and what comes on the new
    connection still wakes the loop and arrives."""
    servers, (program, payload) = socket_ports(SerialLink)
    events: queue.SimpleQueue[LinkEvent] = queue.SimpleQueue()
    adapter = LinkAdapter(UAV, program, payload, sink=events.put)
    adapter.start()
    try:
        autopilot = PiccoloLink(UAV)
        payload_peer, _ = servers[1].accept()
        with payload_peer:
            first, _ = servers[0].accept()
            with first:
                sent = Telemetry(system_time_ms=1, gps=TELEMETRY.gps)
                first.sendall(autopilot.encode_autopilot(sent, ONBOARD_ADDRESS))
                event = events.get(timeout=5.0)
                assert isinstance(event, AutopilotEvent) and event.message == sent
            # The autopilot's end hangs up: the port drops, then reconnects. What comes
            # before the port is open again is discarded by its opening (pyserial).
            second, _ = servers[0].accept()
            wait_until(lambda: program.up and program.reconnects >= 1, 5.0, "the port reopened")
            with second:
                for n in range(2, 5):
                    sent = Telemetry(system_time_ms=n, gps=TELEMETRY.gps)
                    second.sendall(autopilot.encode_autopilot(sent, ONBOARD_ADDRESS))
                    event = events.get(timeout=5.0)
                    assert isinstance(event, AutopilotEvent) and event.message == sent
    finally:
        adapter.stop()
        for server in servers:
            server.close()
