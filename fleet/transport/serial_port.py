"""One serial port of the Piccolo link, opened by pyserial URL, reopened after a drop.

The real backend of `fleet.transport.link.Link`.

Accepts anything `serial.serial_for_url` does: `/dev/ttyAMP0` (57,600 baud on the
aircraft), `socket://host:port` (the simulator), a pty path. Reads never block: the
link loop waits on the port's file descriptor, then reads what is there (thesis 2.7.4).

A `socket://` port is read with one `os.read` on its non-blocking socket: pyserial's
own read with timeout 0 makes a `select` first, on a port the loop's `select` has just
found readable (a syscall and a few Python calls fewer per telemetry packet in
an idle onboard of a simulated fleet). A serial device goes through pyserial: a tty set
up as pyserial does (VMIN = VTIME = 0) reads b'' both when it has nothing and when it
was unplugged, which only pyserial's `select` first tells apart.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import serial
import serial.urlhandler.protocol_socket

from fleet.transport.link import Link

log = logging.getLogger(__name__)

DEFAULT_BAUD = 57_600
READ_CHUNK = 4096
#: pyserial classes whose read is `select` then a read of `fileno()`, a non-blocking
#: socket on which b'' means closed: these are read straight from the descriptor.
_PLAIN_FD_PORTS: tuple[type, ...] = (serial.urlhandler.protocol_socket.Serial,)


@dataclass
class Backoff:
    """Delay between reconnection attempts: doubles from `initial` up to `maximum`."""

    initial: float = 0.1
    maximum: float = 2.0
    current: float = field(init=False, default=0.0)

    def next_delay(self) -> float:
        self.current = self.initial if self.current == 0 else min(self.current * 2, self.maximum)
        return self.current

    def reset(self) -> None:
        self.current = 0.0


@dataclass
class SerialLink(Link):
    """A reconnecting, non-blocking serial port."""

    name: str
    url: str
    baud: int = DEFAULT_BAUD
    backoff: Backoff = field(default_factory=Backoff)
    port: serial.SerialBase | None = None
    reconnects: int = 0
    _retry_at: float = 0.0
    _last_error: str | None = None
    #: The open port's descriptor when it is read directly (`_PLAIN_FD_PORTS`), else None.
    _fd: int | None = None

    @property
    def up(self) -> bool:
        return self.port is not None

    def ensure_open(self, now: float) -> bool:
        """Open the port if it is down and its backoff has passed; True when open."""
        if self.port is not None:
            return True
        if now < self._retry_at:
            return False
        try:
            self.port = serial.serial_for_url(self.url, baudrate=self.baud, timeout=0)
        except (serial.SerialException, OSError, ValueError) as error:
            self._fail(now, error)
            return False
        log.info("%s port open: %s", self.name, self.url)
        self._fd = self._plain_fd(self.port)
        self.backoff.reset()
        self._last_error = None
        return True

    def fileno(self) -> int | None:
        if self.port is None:
            return None
        if self._fd is not None:
            return self._fd
        return self._port_fd(self.port)

    @staticmethod
    def _port_fd(port: serial.SerialBase) -> int | None:
        try:
            return int(port.fileno())
        except (serial.SerialException, OSError, AttributeError, ValueError):
            return None  # e.g. loop://, which only polling can serve

    @classmethod
    def _plain_fd(cls, port: serial.SerialBase) -> int | None:
        if type(port) not in _PLAIN_FD_PORTS:
            return None
        fd = cls._port_fd(port)
        return fd if fd is not None and not os.get_blocking(fd) else None

    def retry_in(self, now: float) -> float:
        return max(0.0, self._retry_at - now)

    def read(self, now: float) -> bytes:
        """Whatever bytes are waiting; b'' when none or when the port is down."""
        if self.port is None:
            return b""
        if self._fd is not None:
            return self._read_fd(self._fd, now)
        try:
            # timeout=0: returns at once with what is there (in_waiting lies on socket://).
            data: bytes = self.port.read(READ_CHUNK)
        except (serial.SerialException, OSError) as error:
            self._fail(now, error)
            return b""
        return data

    def _read_fd(self, fd: int, now: float) -> bytes:
        try:
            data = os.read(fd, READ_CHUNK)
        except (BlockingIOError, InterruptedError):
            return b""  # nothing waiting
        except OSError as error:
            self._fail(now, error)
            return b""
        if not data:  # end of file: the far side closed the socket
            self._fail(now, serial.SerialException("port closed by the other end"))
        return data

    def write(self, data: bytes, now: float) -> bool:
        if self.port is None:
            return False
        try:
            self.port.write(data)
        except (serial.SerialException, OSError) as error:
            self._fail(now, error)
            return False
        return True

    def close(self) -> None:
        if self.port is not None:
            try:
                self.port.close()
            except (serial.SerialException, OSError):
                log.debug("%s port close failed", self.name, exc_info=True)
            self.port = None
            self._fd = None

    def _fail(self, now: float, error: BaseException) -> None:
        was_up = self.port is not None
        self.close()
        delay = self.backoff.next_delay()
        self._retry_at = now + delay
        message = str(error)
        if was_up:
            self.reconnects += 1
            log.warning(
                "%s port %s lost (%s); retrying in %.1f s", self.name, self.url, message, delay
            )
        elif message != self._last_error:
            log.warning("%s port %s: %s; retrying in %.1f s", self.name, self.url, message, delay)
        self._last_error = message
