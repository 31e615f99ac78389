"""The Piccolo-serial adapter's link loop: both ports serviced as bytes arrive, in a thread.

The loop sleeps in `epoll` on both ports and on a wake-up pipe, so an idle link costs
nothing: it wakes when a port has bytes, when something is queued to send, when a
dropped port's reconnection is due, or to stop (a port with no file descriptor, like an
in-memory one, is polled every `poll_interval` instead). It only moves bytes: it reads
whatever each port holds, decodes it with the
link codec and hands the events to `sink`; it writes whatever was queued for it. It
never waits on planning or on Zenoh (thesis 2.7.4, 3.2.2): those run elsewhere and
talk to it through thread-safe queues. A dropped port is reopened with backoff while
the rest of the process carries on, reporting the link as down.
"""

from __future__ import annotations

import contextlib
import logging
import os
import queue
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from fleet.mission.messages import LinkHealth
from fleet.payload.link import LinkEvent, PiccoloLink
from fleet.piccolo.autopilot_messages import AutopilotMessage
from fleet.piccolo.stream_packet import ALL_OPERATOR_INTERFACES
from fleet.transport.link import Link
from onboard.native_thread import name_native_thread

log = logging.getLogger(__name__)

#: The module's own address on the link (docs/protocol.md §1: 0xFFFE is "all operator
#: interfaces"; the module listens in multi-homed mode like one, so it sends as one).
ONBOARD_ADDRESS = ALL_OPERATOR_INTERFACES
#: How often a port without a file descriptor is polled, and the shortest reconnection wait.
POLL_INTERVAL = 0.01
#: The longest the loop sleeps with nothing to do (it wakes early for any work).
IDLE_WAKE = 1.0


@dataclass(frozen=True)
class _Outbound:
    port: str  # "program" or "payload"
    autopilot: AutopilotMessage | None = None
    payload: bytes = b""
    destination: int = 0


class LinkAdapter:
    """Owns the program and payload ports and their codecs; runs the link loop.

    The ports are `Link`s: serial ports in flight (`fleet.transport.serial_port`),
    in-memory pipes in unit tests (`fleet.transport.memory`).
    """

    def __init__(
        self,
        uav_id: int,
        program: Link,
        payload: Link,
        sink: Callable[[LinkEvent], None],
        poll_interval: float = POLL_INTERVAL,
    ) -> None:
        self.uav_id = uav_id
        self.sink = sink
        self.poll_interval = poll_interval
        self.program = program
        self.payload = payload
        self.program_link = PiccoloLink(ONBOARD_ADDRESS)
        self.payload_link = PiccoloLink(ONBOARD_ADDRESS)
        self._outbound: queue.SimpleQueue[_Outbound] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"link-{uav_id}", daemon=True)
        self._lock = threading.Lock()
        self._last_telemetry: float | None = None
        self._wake_read, self._wake_write = os.pipe()
        os.set_blocking(self._wake_read, False)
        os.set_blocking(self._wake_write, False)
        # epoll, not select: the descriptors are registered once (again only when a port
        # reconnects), not handed to the kernel and hooked onto each one's wait queue at
        # every wake-up, 20 a second with telemetry.
        self._poller = select.epoll()
        self._poller.register(self._wake_read, select.EPOLLIN)
        self._watched: list[int] = []
        self._unwatchable: list[int] = []

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.program.close()
        self.payload.close()
        if not self._thread.is_alive() and self._wake_read >= 0:
            self._poller.close()
            os.close(self._wake_read)
            os.close(self._wake_write)
            self._wake_read = self._wake_write = -1  # never close a reused number twice

    # ---- thread-safe API ------------------------------------------------------------
    def send_autopilot(self, message: AutopilotMessage) -> None:
        self._outbound.put(_Outbound("program", autopilot=message, destination=self.uav_id))
        self._wake()

    def send_payload(self, planning_bytes: bytes, destination: int) -> None:
        self._outbound.put(_Outbound("payload", payload=planning_bytes, destination=destination))
        self._wake()

    def _wake(self) -> None:
        # A full pipe already holds a wake-up; a closed one means the loop is gone.
        with contextlib.suppress(BlockingIOError, OSError):
            os.write(self._wake_write, b"\0")

    def note_telemetry(self, at: float) -> None:
        with self._lock:
            self._last_telemetry = at

    def health(self, now: float) -> LinkHealth:
        with self._lock:
            last = self._last_telemetry
            drops = {f"program_{k}": v for k, v in self.program_link.drop_counters().items()}
            drops.update({f"payload_{k}": v for k, v in self.payload_link.drop_counters().items()})
            packets = self.program_link.stream_decoder.packets
            packets += self.payload_link.stream_decoder.packets
        return LinkHealth(
            program_up=self.program.up,
            payload_up=self.payload.up,
            packets=packets,
            drops=drops,
            telemetry_age_s=None if last is None else round(max(0.0, now - last), 3),
        )

    # ---- the loop -------------------------------------------------------------------
    def _run(self) -> None:
        name_native_thread()
        readable: set[int] | None = None  # None: read every port
        while not self._stop.is_set():
            try:
                self._service(time.monotonic(), readable)
            except Exception:  # one bad event must not stop the link
                log.exception("link loop error")
            readable = self._wait(time.monotonic())

    def _wait(self, now: float) -> set[int] | None:
        """Sleep until a port is readable, work is queued, a reconnection is due, or stop.

        The descriptors found readable; None when every port must be read (a wait
        that failed: the next read says why)."""
        timeout = IDLE_WAKE
        watched = []
        for endpoint in (self.program, self.payload):
            fd = endpoint.fileno()
            if fd is not None:
                watched.append(fd)
            elif endpoint.up:
                timeout = min(timeout, self.poll_interval)
            else:
                timeout = min(timeout, max(self.poll_interval, endpoint.retry_in(now)))
        try:
            if watched != self._watched:
                self._watch(watched)
            if self._unwatchable:  # read at every turn, as a port without a descriptor
                timeout = min(timeout, self.poll_interval)
            ready = self._poller.poll(timeout)
        except (OSError, ValueError):  # a port closed under us: the next service says why
            self._watched = []  # registered again, from scratch, at the next wait
            return None
        readable = {fd for fd, _ in ready}
        readable.update(self._unwatchable)
        if self._wake_read in readable:
            with contextlib.suppress(BlockingIOError, OSError):
                os.read(self._wake_read, 4096)
        return readable

    def _watch(self, fds: list[int]) -> None:
        """Register the ports' descriptors `fds` with the poller instead of the last ones.

        A descriptor closed (a port dropped) has left the poller with its file; its
        number may be in use again by the reopened port, registered anew."""
        for fd in self._watched:
            with contextlib.suppress(OSError, ValueError):
                self._poller.unregister(fd)
        self._watched = []
        self._unwatchable = []
        for fd in fds:
            try:
                self._poller.register(fd, select.EPOLLIN)
            except FileExistsError:
                self._poller.modify(fd, select.EPOLLIN)
            except PermissionError:  # a regular file: epoll cannot wait on it
                self._unwatchable.append(fd)
            self._watched.append(fd)

    def _service(self, now: float, readable: set[int] | None = None) -> None:
        """Read the ports with bytes waiting (`readable`; None: all), then send what is
        queued. A port with no descriptor, or one just reopened, is always read. Reading
        only the readable ports saves a syscall per idle port per telemetry packet."""
        for endpoint, link in (
            (self.program, self.program_link),
            (self.payload, self.payload_link),
        ):
            was_up = endpoint.up
            if not endpoint.ensure_open(now):
                continue
            if not was_up:
                self._watched = []  # (re)opened: its descriptor is registered anew
            if readable is not None and was_up:
                fd = endpoint.fileno()
                if fd is not None and fd not in readable:
                    continue
            data = endpoint.read(now)
            if data:
                with self._lock:
                    events = link.feed(data, now)
                for event in events:
                    self.sink(event)
        if not self._outbound.empty():
            self._flush(now)

    def _flush(self, now: float) -> None:
        while True:
            try:
                item = self._outbound.get_nowait()
            except queue.Empty:
                return
            if item.port == "program":
                assert item.autopilot is not None
                with self._lock:
                    data = self.program_link.encode_autopilot(item.autopilot, item.destination)
                if not self.program.write(data, now):
                    log.warning("program port down: %s not sent", type(item.autopilot).__name__)
            else:
                with self._lock:
                    data = self.payload_link.encode_payload(item.payload, item.destination)
                if not self.payload.write(data, now):
                    log.debug("payload port down: %d bytes not sent", len(item.payload))
