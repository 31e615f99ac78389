"""The byte-link interface: what the onboard's link loop needs from a port.

Shaped like python-can's `BusABC`: one small abstract base, a real backend
(`fleet.transport.serial_port.SerialLink`, any pyserial URL) and an in-memory one
(`fleet.transport.memory.MemoryLink`), so the link loop runs unchanged over a serial
port, a simulator socket or a pipe inside one test process.

Every call is non-blocking and takes the caller's clock (`now`, monotonic seconds): a
backend that reconnects schedules its retries on it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod


class Link(ABC):
    """Bytes in and out of one port; reopened by `ensure_open` after a drop."""

    name: str

    @property
    @abstractmethod
    def up(self) -> bool:
        """Whether the port is open now."""

    @abstractmethod
    def ensure_open(self, now: float) -> bool:
        """Open the port if it is down and may be retried; True when open."""

    @abstractmethod
    def read(self, now: float) -> bytes:
        """Whatever bytes are waiting; b'' when none or when the port is down."""

    @abstractmethod
    def write(self, data: bytes, now: float) -> bool:
        """Send `data`; False (nothing sent) when the port is down or drops."""

    @abstractmethod
    def close(self) -> None:
        """Close the port; idempotent."""

    def fileno(self) -> int | None:
        """A file descriptor that turns readable when bytes arrive, to wait on; None when
        the port is down or has none (the loop then polls it)."""
        return None

    def retry_in(self, now: float) -> float:
        """Seconds until a port that is down may be reopened (0: now)."""
        return 0.0
