"""The endpoint on real loopback sockets: frames in and out over udpin, udpout and
tcpin, and hostile input (bad CRC, truncated frames, junk, unknown messages, a flood)
dropped and counted by reason, never raised."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from ground.mavlink.endpoint import (
    PEER_BURST,
    Drop,
    Endpoint,
    EndpointError,
    Incoming,
    InputDrops,
    parse_url,
)
from tests.support.waiting import wait_until

STATION = mavlink2.MAVLink(None, 255, 190)


def frame(message: mavlink2.MAVLink_message | None = None) -> bytes:
    message = message or mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)
    return bytes(message.pack(STATION))


def collect(endpoint: Endpoint, until: int, timeout_s: float = 5.0) -> list[Incoming]:
    got: list[Incoming] = []
    deadline = time.monotonic() + timeout_s
    while len(got) < until and time.monotonic() < deadline:
        got += endpoint.receive(0.05)
    return got


@pytest.fixture
def udpin() -> Iterator[tuple[Endpoint, socket.socket]]:
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops())
    station = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    station.connect(("127.0.0.1", endpoint.local_port))
    station.settimeout(5.0)
    try:
        yield endpoint, station
    finally:
        station.close()
        endpoint.close()


def test_udpin_decodes_a_station_and_answers_it(udpin: tuple[Endpoint, socket.socket]) -> None:
    endpoint, station = udpin
    station.send(frame())
    (incoming,) = collect(endpoint, 1)
    assert incoming.message.get_type() == "HEARTBEAT"
    assert incoming.message.get_srcSystem() == 255
    endpoint.send(lambda _: b"answer")
    assert station.recv(100) == b"answer"


def test_a_station_that_cannot_be_sent_to_never_silences_the_others(
    udpin: tuple[Endpoint, socket.socket],
) -> None:
    endpoint, station = udpin
    # A datagram's source no reply can reach (port 0, as a forged datagram can claim) is
    # a peer before the station, the first the endpoint sends to.
    endpoint._peer(("127.0.0.1", 0)).station = True
    station.send(frame())
    collect(endpoint, 1)
    endpoint.send(lambda _: b"answer")
    assert station.recv(100) == b"answer"
    assert ("127.0.0.1", 0) not in endpoint._peers  # forgotten, not retried every frame


def test_hostile_datagrams_are_dropped_and_counted(
    udpin: tuple[Endpoint, socket.socket],
) -> None:
    endpoint, station = udpin
    good = frame()
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    unknown = bytearray(good)
    unknown[7:10] = (0xFFFFFF).to_bytes(3, "little")  # a message id no dialect has
    for datagram in (bad_crc, good[:7], b"\x00junk" * 40, bytes(unknown), good):
        station.send(datagram)
    got: list[Incoming] = []

    def all_in() -> bool:
        got.extend(endpoint.receive(0.05))
        return bool(got) and endpoint.drops.total() >= 4

    wait_until(all_in, 5.0, "the good frame and four drops")
    assert [m.message.get_type() for m in got] == ["HEARTBEAT"]
    assert endpoint.drops.counts() == {
        Drop.BAD_CRC: 1,
        Drop.TRUNCATED: 1,
        Drop.BAD_PREFIX: 1,
        Drop.UNKNOWN_MESSAGE: 1,
    }


def test_a_frame_cut_short_does_not_eat_the_next_one(
    udpin: tuple[Endpoint, socket.socket],
) -> None:
    endpoint, station = udpin
    station.send(frame()[:12])
    station.send(frame())
    assert [m.message.get_type() for m in collect(endpoint, 1)] == ["HEARTBEAT"]
    assert endpoint.drops.counts() == {Drop.TRUNCATED: 1}


def test_a_flood_beyond_a_peers_share_is_dropped_and_counted(
    udpin: tuple[Endpoint, socket.socket],
) -> None:
    endpoint, station = udpin
    station.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
    # Many frames per datagram, so the kernel's buffer is not what drops them.
    batch = frame() * 50
    sent = 0
    for _ in range(60):
        station.send(batch)
        sent += 50
    got: list[Incoming] = []
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and len(got) + endpoint.drops.total() < sent:
        got += endpoint.receive(0.05)
    assert endpoint.drops.counts().get(Drop.FLOOD, 0) > 0
    assert PEER_BURST <= len(got) < sent


def test_a_listening_endpoint_on_port_0_says_the_port_it_bound() -> None:
    for kind in ("udpin", "tcpin"):
        endpoint = Endpoint(f"{kind}:127.0.0.1:0", InputDrops())
        try:
            assert endpoint.local_port != 0
            assert endpoint.url == f"{kind}:127.0.0.1:{endpoint.local_port}"
        finally:
            endpoint.close()
    out = Endpoint("udpout:127.0.0.1:14550", InputDrops())
    try:
        assert out.url == "udpout:127.0.0.1:14550"  # where it sends, not its own port
    finally:
        out.close()


def test_tcpin_decodes_a_frame_split_across_reads() -> None:
    endpoint = Endpoint("tcpin:127.0.0.1:0", InputDrops())
    try:
        with socket.create_connection(("127.0.0.1", endpoint.local_port), timeout=5) as station:
            collect(endpoint, 0, 0.2)  # accept
            data = frame()
            station.sendall(data[:5])
            assert collect(endpoint, 1, 0.3) == []
            station.sendall(data[5:])
            (incoming,) = collect(endpoint, 1)
            assert incoming.message.get_type() == "HEARTBEAT"
            endpoint.send(lambda _: b"hello")
            assert station.recv(5) == b"hello"
    finally:
        endpoint.close()
    assert endpoint.drops.total() == 0


def test_udpout_sends_to_the_station_and_hears_its_answer() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as station:
        station.bind(("127.0.0.1", 0))
        station.settimeout(5.0)
        port = station.getsockname()[1]
        endpoint = Endpoint(f"udpout:127.0.0.1:{port}", InputDrops())
        try:
            endpoint.send(lambda _: b"beat")
            data, address = station.recvfrom(100)
            assert data == b"beat"
            station.sendto(frame(), address)
            (incoming,) = collect(endpoint, 1)
            assert incoming.message.get_type() == "HEARTBEAT"
        finally:
            endpoint.close()


def test_udpout_with_nobody_listening_is_not_an_error() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    endpoint = Endpoint(f"udpout:127.0.0.1:{port}", InputDrops())
    try:
        for _ in range(3):
            endpoint.send(lambda _: b"beat")
            assert endpoint.receive(0.05) == []
    finally:
        endpoint.close()


@pytest.mark.parametrize(
    "url", ["udp:127.0.0.1:14550", "udpout:14550", "udpout:host:port", "tcpin:h:70000", "x"]
)
def test_bad_urls_are_refused_by_name(url: str) -> None:
    with pytest.raises(EndpointError, match=r"udpout|port"):
        parse_url(url)


def test_a_port_in_use_is_a_clear_error() -> None:
    first = Endpoint("udpin:127.0.0.1:0", InputDrops())
    try:
        with pytest.raises(EndpointError, match="in use"):
            Endpoint(f"udpin:127.0.0.1:{first.local_port}", InputDrops())
    finally:
        first.close()
