"""Who the endpoint answers: stations only after a valid heartbeat (signed, when the
gateway signs), never a peer that sent anything else, and peers that never send one
cannot take the stations' places."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from ground.mavlink.endpoint import (
    MAX_PENDING,
    MAX_STATIONS,
    Drop,
    Endpoint,
    Incoming,
    InputDrops,
)
from ground.mavlink.signing import (
    SigningKeyError,
    StationKey,
    Verifier,
    load_keys,
    passphrase_secret,
    signing_encoder,
    timestamp_now,
)
from tests.support.waiting import wait_until

OPERATOR = StationKey("operator", passphrase_secret("correct horse"))
OTHER = StationKey("backup", passphrase_secret("battery staple"))


def station_encoder(
    key: StationKey | None = None, timestamp: int | None = None
) -> mavlink2.MAVLink:
    encoder = mavlink2.MAVLink(None, 255, 190)
    if key is not None:
        encoder.signing.secret_key = key.secret
        encoder.signing.sign_outgoing = True
        encoder.signing.timestamp = timestamp if timestamp is not None else timestamp_now()
    return encoder


def heartbeat(encoder: mavlink2.MAVLink) -> bytes:
    message = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)
    return bytes(message.pack(encoder))


def command(encoder: mavlink2.MAVLink) -> bytes:
    message = mavlink2.MAVLink_command_long_message(74, 1, 20, 0, 0, 0, 0, 0, 0, 0, 0)  # RTL
    return bytes(message.pack(encoder))


def pump(endpoint: Endpoint, until: int = 1, timeout_s: float = 3.0) -> list[Incoming]:
    got: list[Incoming] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and len(got) < until:
        got += endpoint.receive(0.05)
    return got


def settle(endpoint: Endpoint, drops: int) -> None:
    """Read until `drops` inputs were dropped in all."""
    wait_until(lambda: bool(endpoint.receive(0.05)) or endpoint.drops.total() >= drops, 5.0)


@pytest.fixture
def udpin() -> Iterator[Endpoint]:
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops())
    yield endpoint
    endpoint.close()


def station(endpoint: Endpoint) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.connect(("127.0.0.1", endpoint.local_port))
    sock.settimeout(0.3)
    return sock


def answered(sock: socket.socket) -> bytes:
    try:
        return sock.recv(65535)
    except TimeoutError:
        return b""


def nothing_waiting(sock: socket.socket) -> bool:
    sock.setblocking(False)
    try:
        sock.recv(65535)
    except BlockingIOError:
        return True
    return False


def test_one_byte_from_a_stranger_is_never_answered(udpin: Endpoint) -> None:
    with station(udpin) as stranger:
        stranger.send(b"\x00")
        settle(udpin, 1)
        udpin.send(lambda _: b"the fleet's streams" * 1000)
        assert answered(stranger) == b""  # no reflection: nothing larger, nothing at all


def test_a_command_before_a_heartbeat_is_dropped_and_the_heartbeat_makes_a_station(
    udpin: Endpoint,
) -> None:
    with station(udpin) as sock:
        encoder = station_encoder()
        sock.send(command(encoder))
        settle(udpin, 1)
        assert udpin.drops.counts() == {Drop.NO_HEARTBEAT: 1}
        sock.send(heartbeat(encoder) + command(encoder))
        got = pump(udpin, 2)
        assert [m.message.get_type() for m in got] == ["HEARTBEAT", "COMMAND_LONG"]
        udpin.send(lambda _: b"answer")
        assert answered(sock) == b"answer"


def test_peers_without_a_heartbeat_cannot_lock_stations_out(udpin: Endpoint) -> None:
    idle = [station(udpin) for _ in range(MAX_PENDING + MAX_STATIONS)]
    try:
        for sock in idle:
            sock.send(b"\x00")
        settle(udpin, len(idle))
        with station(udpin) as honest:
            honest.send(heartbeat(station_encoder()))
            assert [m.message.get_type() for m in pump(udpin)] == ["HEARTBEAT"]
            udpin.send(lambda _: b"answer")
            assert answered(honest) == b"answer"
        # Sent in the same call as the honest station's answer, which has arrived.
        assert all(nothing_waiting(sock) for sock in idle)
    finally:
        for sock in idle:
            sock.close()


def test_idle_tcp_connections_cannot_lock_stations_out() -> None:
    endpoint = Endpoint("tcpin:127.0.0.1:0", InputDrops())
    idle: list[socket.socket] = []
    try:
        for _ in range(MAX_PENDING + MAX_STATIONS):
            idle.append(socket.create_connection(("127.0.0.1", endpoint.local_port), timeout=5))
            endpoint.receive(0.01)  # accepted
        with socket.create_connection(("127.0.0.1", endpoint.local_port), timeout=5) as honest:
            pump(endpoint, 0, 0.3)
            honest.sendall(heartbeat(station_encoder()))
            assert [m.message.get_type() for m in pump(endpoint)] == ["HEARTBEAT"]
            endpoint.send(lambda _: b"answer")
            honest.settimeout(5)
            assert honest.recv(6) == b"answer"
    finally:
        for sock in idle:
            sock.close()
        endpoint.close()


def test_a_silent_station_is_let_go() -> None:
    now = [0.0]
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops(), clock=lambda: now[0])
    try:
        with station(endpoint) as sock:
            sock.send(heartbeat(station_encoder()))
            pump(endpoint)
            assert endpoint.stations() == 1
            now[0] = 100.0
            endpoint.receive(0.01)
            assert endpoint.stations() == 0
            endpoint.send(lambda _: b"answer")
            assert answered(sock) == b""
    finally:
        endpoint.close()


# ---- signing ----------------------------------------------------------------------------------
@pytest.fixture
def signed() -> Iterator[Endpoint]:
    endpoint = Endpoint("udpin:127.0.0.1:0", InputDrops(), verifier=Verifier((OPERATOR, OTHER)))
    yield endpoint
    endpoint.close()


def test_unsigned_or_wrongly_signed_frames_are_refused_and_counted(signed: Endpoint) -> None:
    with station(signed) as sock:
        for encoder in (station_encoder(), station_encoder(StationKey("x", b"\x01" * 32))):
            sock.send(heartbeat(encoder) + command(encoder))
        settle(signed, 4)
        assert signed.drops.counts() == {Drop.UNSIGNED: 2, Drop.BAD_SIGNATURE: 2}
        assert signed.stations() == 0
        signed.send(lambda _: b"answer")
        assert answered(sock) == b""


def test_a_signed_station_is_answered_with_its_own_secret(signed: Endpoint) -> None:
    with station(signed) as sock:
        encoder = station_encoder(OTHER)
        sock.send(heartbeat(encoder) + command(encoder))
        assert [m.message.get_type() for m in pump(signed, 2)] == ["HEARTBEAT", "COMMAND_LONG"]
        signed.send(lambda key: bytes(mavlink2.MAVLink_heartbeat_message(1, 8, 0, 0, 0, 3).pack(
            signing_encoder(74, key))))  # fmt: skip
        data = answered(sock)
        checker = mavlink2.MAVLink(None)
        checker.signing.secret_key = OTHER.secret  # pymavlink's own check of our signature
        (message,) = checker.parse_buffer(data) or []
        assert message.get_type() == "HEARTBEAT" and message.get_signed()


def test_a_replayed_frame_and_a_stale_new_stream_are_refused(signed: Endpoint) -> None:
    with station(signed) as sock:
        encoder = station_encoder(OPERATOR)
        beat = heartbeat(encoder)
        rtl = command(encoder)
        sock.send(beat + rtl)
        assert len(pump(signed, 2)) == 2
        sock.send(rtl)  # the same frame again, as a recorder of the link would
        settle(signed, 1)
        stale = station_encoder(OPERATOR, timestamp_now() - 120 * 100_000)
        stale.srcComponent = 191  # a new stream, two minutes old
        sock.send(heartbeat(stale))
        settle(signed, 2)
        assert signed.drops.counts() == {Drop.REPLAYED: 2}


def test_the_key_file_holds_a_passphrase_per_station_readable_by_its_owner(
    tmp_path: Path,
) -> None:
    path = tmp_path / "stations"
    path.write_text("# name passphrase\noperator correct horse\nbackup battery staple\n")
    path.chmod(0o600)
    assert load_keys(path) == (OPERATOR, OTHER)
    path.chmod(0o644)
    with pytest.raises(SigningKeyError, match="chmod 600"):
        load_keys(path)
    path.write_text("operator\n")
    path.chmod(0o600)
    with pytest.raises(SigningKeyError, match="line 1: expected NAME PASSPHRASE"):
        load_keys(path)
