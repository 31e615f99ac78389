"""One serial port of the Piccolo link, opened by pyserial URL, reopened after a drop.

The real backend of `fleet.transport.link.Link`.

Accepts anything `serial.serial_for_url` does: `/dev/ttyAMP0` (57,600 baud on the
aircraft), `socket://host:port` (the simulator), a pty path. Reads never block: the
link loop polls every port every few milliseconds (thesis 2.7.4).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import serial

from fleet.transport.link import Link

log = logging.getLogger(__name__)

DEFAULT_BAUD = 57_600
READ_CHUNK = 4096


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
        self.backoff.reset()
        self._last_error = None
        return True

    def fileno(self) -> int | None:
        if self.port is None:
            return None
        try:
            return int(self.port.fileno())
        except (serial.SerialException, OSError, AttributeError, ValueError):
            return None  # e.g. loop://, which only polling can serve

    def retry_in(self, now: float) -> float:
        return max(0.0, self._retry_at - now)

    def read(self, now: float) -> bytes:
        """Whatever bytes are waiting; b'' when none or when the port is down."""
        if self.port is None:
            return b""
        try:
            # timeout=0: returns at once with what is there (in_waiting lies on socket://).
            data: bytes = self.port.read(READ_CHUNK)
        except (serial.SerialException, OSError) as error:
            self._fail(now, error)
            return b""
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
