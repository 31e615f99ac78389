"""The simulator's I/O edge: listeners, ptys, and the loop that paces simulated time.

One thread, one `selectors` loop, any number of simulated autopilots stepped in
lockstep. Per aircraft:

* program port: a TCP listener (pyserial URL ``socket://host:port``) accepting any
  number of clients, each its own serial line to the autopilot; or, with ``pty``, a
  pseudo-terminal whose slave path a program opens like a serial device;
* payload port: the same, the onboard end of the transparent payload pipe;
* ground port: a TCP listener, the ground end of the payload pipe.

Simulated time runs `speedup` times faster than the monotonic clock; speedup 0 steps as
fast as the CPU allows (between batches of steps the loop still serves the sockets).
The loop never skips a step: when the CPU cannot keep up, simulated time lags and a
warning says so.

`stop()` may be called from another thread or a signal handler: it wakes the loop
through a socket pair, and `run()` returns within one iteration.
"""

from __future__ import annotations

import contextlib
import enum
import errno
import logging
import math
import os
import selectors
import socket
import threading
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from fleet.piccolo.stream_queue import StreamQueue
from fleet.sim.autopilot import STEP_MS, ProgramConnection, SimulatedAutopilot, bounded_buffer
from fleet.sim.truth_log import TruthLog

logger = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PROGRAM_PORT = 5760
DEFAULT_PAYLOAD_PORT = 5860
DEFAULT_GROUND_PORT = 5960
DEFAULT_SPEEDUP = 1.0

# At most this many steps (1 s simulated) between two looks at the sockets, so that a
# high speedup never starves the I/O.
_MAX_BATCH_STEPS = 50
# The loop wakes at least this often (s) even with nothing to do, to notice `duration`.
_MAX_WAIT_S = 0.05
_READ_SIZE = 65536
_LISTEN_BACKLOG = 8
#: How often (wall seconds) dropped input and a lagging clock are reported, at most.
DEFAULT_REPORT_INTERVAL_S = 10.0


class _Kind(enum.Enum):
    PROGRAM_LISTENER = "program listener"
    PAYLOAD_LISTENER = "payload listener"
    GROUND_LISTENER = "ground listener"
    PROGRAM = "program"
    PAYLOAD = "payload"
    GROUND = "ground"
    WAKE = "wake"


_LISTENED = {
    _Kind.PROGRAM_LISTENER: _Kind.PROGRAM,
    _Kind.PAYLOAD_LISTENER: _Kind.PAYLOAD,
    _Kind.GROUND_LISTENER: _Kind.GROUND,
}


@dataclass(frozen=True, slots=True)
class Endpoints:
    """Where one simulated autopilot's ports are, as pyserial URLs or device paths."""

    piccolo_id: int
    program: str
    payload: str
    ground: str

    def line(self) -> str:
        """The line `fleet sim` prints for this aircraft."""
        return (
            f"uav {self.piccolo_id} program={self.program} payload={self.payload} "
            f"ground={self.ground}"
        )


@dataclass(eq=False)
class _Channel:
    """Anything registered with the selector: a listener, a client, a pty, the wake pair."""

    kind: _Kind
    uav: _Uav | None
    name: str
    sock: socket.socket | None = None
    fd: int = -1  #: a pty master, when `sock` is None
    output: StreamQueue = field(default_factory=bounded_buffer)
    connection: ProgramConnection | None = None
    permanent: bool = False  #: a pty: never "disconnects"

    def fileno(self) -> int:
        return self.sock.fileno() if self.sock is not None else self.fd

    def recv(self) -> bytes:
        if self.sock is not None:
            return self.sock.recv(_READ_SIZE)
        return os.read(self.fd, _READ_SIZE)

    def send(self, data: bytes) -> int:
        if self.sock is not None:
            return self.sock.send(data)
        return os.write(self.fd, data)


@dataclass(eq=False)
class _Uav:
    autopilot: SimulatedAutopilot
    channels: list[_Channel] = field(default_factory=list)  #: clients and ptys
    owned_fds: list[int] = field(default_factory=list)  #: pty fds to close
    reported_drops: int = 0

    def clients(self, kind: _Kind) -> list[_Channel]:
        return [channel for channel in self.channels if channel.kind is kind]


def _url(host: str, port: int) -> str:
    return f"socket://[{host}]:{port}" if ":" in host else f"socket://{host}:{port}"


class SimServer:
    """Serves simulated autopilots on sockets or ptys and paces their simulated time."""

    def __init__(
        self,
        autopilots: Sequence[SimulatedAutopilot],
        *,
        host: str = DEFAULT_HOST,
        program_port: int = DEFAULT_PROGRAM_PORT,
        payload_port: int = DEFAULT_PAYLOAD_PORT,
        ground_port: int = DEFAULT_GROUND_PORT,
        speedup: float = DEFAULT_SPEEDUP,
        use_pty: bool = False,
        clock: Callable[[], float] = time.monotonic,
        report_interval: float = DEFAULT_REPORT_INTERVAL_S,
        truth: TruthLog | None = None,
    ) -> None:
        if not autopilots:
            raise ValueError("no autopilot to serve")
        if not (math.isfinite(speedup) and speedup >= 0.0):
            raise ValueError(f"speedup must be a finite number >= 0, got {speedup}")
        for name, port in (
            ("program", program_port),
            ("payload", payload_port),
            ("ground", ground_port),
        ):
            last = port + len(autopilots) - 1 if port else 0
            if not 0 <= port <= 65535 or last > 65535:
                raise ValueError(f"{name} ports {port}-{last} are not all valid TCP ports")
        self.speedup = speedup
        self._host = host
        self._ports = (program_port, payload_port, ground_port)
        self._use_pty = use_pty
        self._clock = clock
        self._report_interval = report_interval
        self._truth = truth
        self._uavs = [_Uav(autopilot) for autopilot in autopilots]
        self._selector = selectors.DefaultSelector()
        self._listeners: list[_Channel] = []
        self._stop = threading.Event()
        self._wake_read, self._wake_write = socket.socketpair()
        self._wake_read.setblocking(False)
        self._wake_write.setblocking(False)
        self._selector.register(
            self._wake_read, selectors.EVENT_READ, _Channel(_Kind.WAKE, None, "wake")
        )
        self._endpoints: list[Endpoints] | None = None
        self._closed = False

    # -- set up and tear down -------------------------------------------------------

    def open(self) -> list[Endpoints]:
        """Bind every listener (and open ptys); return where each aircraft is served."""
        if self._closed:
            raise RuntimeError("server is closed")
        if self._endpoints is not None:
            return list(self._endpoints)
        try:
            endpoints = [self._open_uav(i, uav) for i, uav in enumerate(self._uavs)]
        except BaseException:
            self.close()
            raise
        self._endpoints = endpoints
        return list(endpoints)

    def _open_uav(self, index: int, uav: _Uav) -> Endpoints:
        program_port, payload_port, ground_port = (
            port + index if port else 0 for port in self._ports
        )
        if self._use_pty:
            program = self._open_pty(uav, _Kind.PROGRAM)
            payload = self._open_pty(uav, _Kind.PAYLOAD)
        else:
            program = self._listen(uav, _Kind.PROGRAM_LISTENER, program_port)
            payload = self._listen(uav, _Kind.PAYLOAD_LISTENER, payload_port)
        ground = self._listen(uav, _Kind.GROUND_LISTENER, ground_port)
        return Endpoints(uav.autopilot.piccolo_id, program, payload, ground)

    def _listen(self, uav: _Uav, kind: _Kind, port: int) -> str:
        sock = socket.socket(socket.AF_INET6 if ":" in self._host else socket.AF_INET)
        try:
            # A restarted simulator must not wait for the old sockets' TIME_WAIT.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((self._host, port))
            sock.listen(_LISTEN_BACKLOG)
            sock.setblocking(False)
        except OSError as error:
            sock.close()
            raise OSError(
                error.errno,
                f"uav {uav.autopilot.piccolo_id}: cannot listen for the {kind.value} "
                f"on {self._host}:{port}: {error.strerror}",
            ) from error
        bound_port = sock.getsockname()[1]
        channel = _Channel(kind, uav, f"{kind.value} {self._host}:{bound_port}", sock=sock)
        self._listeners.append(channel)
        self._selector.register(sock, selectors.EVENT_READ, channel)
        logger.info(
            "uav %d: %s on %s", uav.autopilot.piccolo_id, kind.value, _url(self._host, bound_port)
        )
        return _url(self._host, bound_port)

    def _open_pty(self, uav: _Uav, kind: _Kind) -> str:
        master, slave = os.openpty()
        uav.owned_fds.extend((master, slave))
        # Raw: no echo and no line editing, a byte-transparent serial line. The slave
        # stays open here so that a client closing it does not hang the master up, and
        # the next client is served again.
        tty.setraw(slave)
        os.set_blocking(master, False)
        path = os.ttyname(slave)
        channel = _Channel(kind, uav, f"{kind.value} pty {path}", fd=master, permanent=True)
        if kind is _Kind.PROGRAM:
            channel.connection = uav.autopilot.open_program(channel.name)
            channel.output = channel.connection.output
        uav.channels.append(channel)
        self._selector.register(master, selectors.EVENT_READ, channel)
        logger.info("uav %d: %s on %s", uav.autopilot.piccolo_id, kind.value, path)
        return path

    def close(self) -> None:
        """Close every socket and pty, and the truth log. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for uav in self._uavs:
            for channel in list(uav.channels):
                self._drop_channel(channel, reason=None)
            for fd in uav.owned_fds:
                try:
                    os.close(fd)
                except OSError:
                    logger.debug("pty fd %d already closed", fd)
            uav.owned_fds.clear()
        for channel in self._listeners:
            self._unregister(channel)
            if channel.sock is not None:
                channel.sock.close()
        self._listeners.clear()
        self._selector.close()
        self._wake_read.close()
        self._wake_write.close()
        if self._truth is not None:
            self._truth.close()

    def __enter__(self) -> SimServer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- the loop -------------------------------------------------------------------

    @property
    def time_ms(self) -> int:
        """Simulated time (ms); every aircraft is at the same instant between steps."""
        return self._uavs[0].autopilot.time_ms

    def stop(self) -> None:
        """Make `run` return. Safe from another thread and from a signal handler."""
        self._stop.set()
        # OSError: the pair is full (the loop is already being woken) or closed.
        with contextlib.suppress(OSError):
            self._wake_write.send(b"\0")

    def run(self, duration: float | None = None) -> None:
        """Serve and step until `stop()`, or for `duration` wall seconds if given."""
        if self._endpoints is None:
            self.open()
        start_wall = self._clock()
        start_sim = self.time_ms
        last_report = start_wall
        while not self._stop.is_set():
            now = self._clock()
            if duration is not None and now - start_wall >= duration:
                break
            if self.speedup > 0.0:
                target_ms = start_sim + int((now - start_wall) * self.speedup * 1000.0)
                due = max((target_ms - self.time_ms) // STEP_MS, 0)
            else:
                due = _MAX_BATCH_STEPS
            batch = min(due, _MAX_BATCH_STEPS)
            for _ in range(batch):
                for uav in self._uavs:
                    uav.autopilot.step()
                    if self._truth is not None:
                        pilot = uav.autopilot
                        self._truth.note(pilot.piccolo_id, pilot.time_ms, pilot.position())
            self._flush()
            if due > batch or self.speedup == 0.0:
                timeout = 0.0
            else:
                next_step = start_wall + (self.time_ms + STEP_MS - start_sim) / (
                    1000.0 * self.speedup
                )
                timeout = min(max(next_step - self._clock(), 0.0), _MAX_WAIT_S)
            for key, _ in self._selector.select(timeout):
                self._ready(key.data)
            self._flush()
            if now - last_report >= self._report_interval:
                last_report = now
                self._report(due - batch)

    def _report(self, lag_steps: int) -> None:
        if lag_steps > _MAX_BATCH_STEPS:
            logger.warning(
                "simulated time lags the requested speedup %g by %.1f s: the CPU cannot keep up",
                self.speedup,
                lag_steps * STEP_MS / 1000.0,
            )
        for uav in self._uavs:
            drops = uav.autopilot.link_drops()
            total = sum(drops.values())
            if total != uav.reported_drops:
                uav.reported_drops = total
                nonzero = {name: count for name, count in sorted(drops.items()) if count}
                logger.warning(
                    "uav %d: program port dropped so far: %s", uav.autopilot.piccolo_id, nonzero
                )

    def _ready(self, channel: _Channel) -> None:
        if channel.kind is _Kind.WAKE:
            with contextlib.suppress(BlockingIOError):
                self._wake_read.recv(_READ_SIZE)
        elif channel.kind in _LISTENED:
            self._accept(channel)
        else:
            self._read(channel)

    def _accept(self, listener: _Channel) -> None:
        assert listener.sock is not None and listener.uav is not None
        try:
            sock, address = listener.sock.accept()
        except (BlockingIOError, ConnectionAbortedError):
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        uav = listener.uav
        kind = _LISTENED[listener.kind]
        name = f"{kind.value} client {address[0]}:{address[1]}"
        channel = _Channel(kind, uav, name, sock=sock)
        if kind is _Kind.PROGRAM:
            channel.connection = uav.autopilot.open_program(name)
            channel.output = channel.connection.output
        uav.channels.append(channel)
        self._selector.register(sock, selectors.EVENT_READ, channel)
        logger.info("uav %d: %s connected", uav.autopilot.piccolo_id, name)

    def _read(self, channel: _Channel) -> None:
        assert channel.uav is not None
        try:
            data = channel.recv()
        except (BlockingIOError, InterruptedError):
            return
        except OSError as error:
            if channel.permanent and error.errno == errno.EIO:
                return  # a pty with no client: nothing to read, nothing lost
            self._drop_channel(channel, reason=str(error))
            return
        if not data:
            if not channel.permanent:
                self._drop_channel(channel, reason="closed by the client")
            return
        autopilot = channel.uav.autopilot
        if channel.kind is _Kind.PROGRAM:
            assert channel.connection is not None
            autopilot.receive(channel.connection, data)
        elif channel.kind is _Kind.PAYLOAD:
            autopilot.payload.from_onboard(data)
        else:
            autopilot.payload.from_ground(data)

    def _flush(self) -> None:
        # Twice a loop turn over every aircraft: only what has bytes costs more than a
        # length check (at 100 aircraft, most have nothing to send at a given turn).
        for uav in self._uavs:
            pipe = uav.autopilot.payload
            # The pipe keeps its bytes (bounded) until somebody on the far side is there.
            for buffer, kind in ((pipe.to_ground, _Kind.GROUND), (pipe.to_onboard, _Kind.PAYLOAD)):
                if len(buffer):
                    readers = uav.clients(kind)
                    if readers:
                        data = buffer.take()
                        for reader in readers:
                            reader.output.append(data)
            pending = [channel for channel in uav.channels if len(channel.output)]
            for channel in pending:  # a copy: a failed write drops its channel
                self._write(channel)

    def _write(self, channel: _Channel) -> None:
        data = bytes(channel.output.view())
        try:
            sent = channel.send(data)
        except (BlockingIOError, InterruptedError):
            return  # the reader is slow: the bounded buffer keeps the newest bytes
        except OSError as error:
            if channel.permanent:
                channel.output.take()  # a pty nobody has open: the bytes are lost
                return
            self._drop_channel(channel, reason=str(error))
            return
        channel.output.consume(sent)

    def _drop_channel(self, channel: _Channel, reason: str | None) -> None:
        uav = channel.uav
        assert uav is not None
        if channel in uav.channels:
            uav.channels.remove(channel)
        if channel.connection is not None:
            uav.autopilot.close_program(channel.connection)
        self._unregister(channel)
        if channel.sock is not None:
            channel.sock.close()
        if reason is not None:
            logger.info(
                "uav %d: %s disconnected (%s)", uav.autopilot.piccolo_id, channel.name, reason
            )

    def _unregister(self, channel: _Channel) -> None:
        try:
            self._selector.unregister(channel.fileno())
        except (KeyError, ValueError, OSError):
            logger.debug("%s was not registered", channel.name)
