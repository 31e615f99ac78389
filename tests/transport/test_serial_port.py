"""The serial port edge: backoff between reconnection attempts, and a real reconnect over
socket:// (pyserial's TCP URL, as the simulator serves it)."""

from __future__ import annotations

import os
import pty
import socket
import tty
from collections.abc import Iterator

import pytest

from fleet.transport.serial_port import Backoff, SerialLink
from tests.support.waiting import wait_until


def test_backoff_doubles_up_to_its_maximum_and_resets() -> None:
    backoff = Backoff(initial=0.1, maximum=0.5)
    assert [backoff.next_delay() for _ in range(5)] == [0.1, 0.2, 0.4, 0.5, 0.5]
    backoff.reset()
    assert backoff.next_delay() == 0.1


def test_a_bad_url_is_down_and_retried_only_after_the_backoff() -> None:
    link = SerialLink("program", "nosuchscheme://x", backoff=Backoff(initial=1.0, maximum=4.0))
    assert not link.ensure_open(0.0) and not link.up
    assert link.read(0.0) == b"" and not link.write(b"x", 0.0)
    assert not link.ensure_open(0.5)  # within the backoff: not even tried
    assert link.backoff.current == 1.0
    assert not link.ensure_open(1.0)  # tried again, failed again: the delay doubles
    assert link.backoff.current == 2.0
    assert link.reconnects == 0  # never up, so never lost


@pytest.fixture
def listener() -> Iterator[tuple[socket.socket, int]]:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))  # the port the OS gives, held from now on
    port = server.getsockname()[1]
    server.listen()
    server.settimeout(10.0)
    try:
        yield server, port
    finally:
        server.close()


def read_until(link: SerialLink, count: int, what: str) -> bytes:
    """What `link` reads until it holds `count` bytes (waited for, at most 5 s)."""
    received = bytearray()

    def enough() -> bool:
        received.extend(link.read(0.0))
        return len(received) >= count

    wait_until(enough, 5.0, what)
    return bytes(received)


def test_a_dropped_socket_is_counted_and_reopened(listener: tuple[socket.socket, int]) -> None:
    server, port = listener
    link = SerialLink("program", f"socket://127.0.0.1:{port}", backoff=Backoff(0.05, 0.1))
    assert link.ensure_open(0.0)
    peer, _ = server.accept()
    with peer:
        peer.sendall(b"hello")
        assert read_until(link, 5, "the bytes sent") == b"hello"
        assert link.write(b"back", 0.0)
        assert peer.recv(16) == b"back"
    # The far end closed: the next read notices, closes the port and schedules a retry.
    wait_until(lambda: link.read(1.0) == b"" and not link.up, 5.0, "the drop to be seen")
    assert link.reconnects == 1
    assert not link.ensure_open(1.0)  # within the backoff
    assert link.ensure_open(2.0)
    again, _ = server.accept()
    again.close()
    link.close()
    assert not link.up


def test_a_socket_is_read_from_its_descriptor_every_byte_in_order(
    listener: tuple[socket.socket, int],
) -> None:
    """A socket:// port is read with one os.read on its descriptor: every
    byte arrives in order, and a read with nothing waiting is b'' without a drop."""
    server, port = listener
    link = SerialLink("program", f"socket://127.0.0.1:{port}")
    assert link.ensure_open(0.0)
    peer, _ = server.accept()
    with peer:
        assert link.fileno() is not None and link._fd == link.fileno()
        assert link.read(0.0) == b"" and link.up  # nothing waiting: no drop
        sent = bytes(range(256)) * 64  # more than one read's worth
        peer.sendall(sent)
        assert read_until(link, len(sent), "every byte sent") == sent
    link.close()


def test_a_pty_is_read_through_pyserial() -> None:
    """A serial device keeps pyserial's read: its b'' means nothing waiting, not a drop."""
    master, slave = pty.openpty()
    link = SerialLink("program", os.ttyname(slave))
    try:
        tty.setraw(master)
        assert link.ensure_open(0.0)
        assert link._fd is None
        assert link.read(0.0) == b"" and link.up
        os.write(master, b"hello")
        assert read_until(link, 5, "the bytes written") == b"hello"
    finally:
        link.close()
        os.close(slave)
        os.close(master)
