"""The gateway's MAVLink endpoint: where ground stations connect, and what comes in.

`udpout:HOST:PORT` sends to a ground station listening there (QGroundControl's 14550)
and hears its answers on the same socket; `udpin:HOST:PORT` listens for stations;
`tcpin:HOST:PORT` accepts them over TCP. Every frame is decoded by pymavlink's MAVLink 2
parser in its robust mode, one parser per peer: a frame with a bad CRC, a bad prefix, an
unknown message id, a datagram that ends inside a frame (truncated), or more than a
peer's share of messages a second (a flood; a datagram arriving once the share is spent
is dropped unread, counted once) is dropped and counted (`InputDrops`), never raised.
At most `READ_BUDGET` reads are done per `receive`, so a flood cannot starve the
gateway's own heartbeats.

**Stations.** A peer becomes a station, one of `MAX_STATIONS`, only with a valid
HEARTBEAT (signed, when the gateway signs: `signing`); until then nothing it sends but
its heartbeat is taken (`no_heartbeat`) and nothing is sent to it, so a datagram from
a forged address is never answered with the fleet's streams (no reflection), and peers
that never send one cannot fill the stations' places: they wait in a table of their own
(`MAX_PENDING`, the oldest evicted first, each forgotten after `PENDING_TTL_S`). A
station silent for `STATION_TTL_S` (no heartbeat) is let go (a TCP one disconnected).
The `udpout` address is the station the operator named: it is sent to from the start.
"""

from __future__ import annotations

import logging
import selectors
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

from pymavlink.dialects.v20 import common as mavlink2

from fleet.errors import FleetError
from fleet.transport.cli import in_use_advice
from ground.mavlink.signing import StationKey, Verdict, Verifier

log = logging.getLogger(__name__)

#: Stations (peers that sent a valid heartbeat) at most, and how long one may be silent.
MAX_STATIONS = 8
STATION_TTL_S = 15.0
#: Peers without a heartbeat yet, at most (UDP addresses, TCP connections), and how long
#: one is kept waiting for it.
MAX_PENDING = 64
PENDING_TTL_S = 10.0
READ_BUDGET = 256
#: A peer's share: messages a second, and the burst it may send at once.
PEER_RATE_HZ = 400.0
PEER_BURST = 800.0
_DATAGRAM = 65535


class EndpointError(FleetError, ValueError):
    """An endpoint that cannot be parsed or opened."""


class Drop(StrEnum):
    """Why an input was dropped."""

    BAD_CRC = "bad_crc"
    BAD_PREFIX = "bad_prefix"
    UNKNOWN_MESSAGE = "unknown_message"
    MALFORMED = "malformed"
    TRUNCATED = "truncated"
    FLOOD = "flood"
    #: A valid heartbeat while every station's place is taken
    TOO_MANY_PEERS = "too_many_peers"
    #: From a peer that has sent no valid heartbeat (not a station)
    NO_HEARTBEAT = "no_heartbeat"
    #: Signing required: a frame without a signature, one no station's secret signed,
    #: or one whose timestamp is not newer than its stream's last
    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad_signature"
    REPLAYED = "replayed"
    #: Another station's MISSION_COUNT while an upload to the vehicle is open
    BUSY = "busy"
    #: Decoded, but refused by the gateway (a MISSION_COUNT out of range)
    REFUSED = "refused"
    #: Decoded, but addressed to a system id the gateway does not show
    UNKNOWN_SYSTEM = "unknown_system"


class InputDrops:
    """Counts of dropped input by reason (the gateway's one thread updates it)."""

    def __init__(self) -> None:
        self._counts: dict[Drop, int] = {}

    def add(self, reason: Drop, count: int = 1) -> None:
        self._counts[reason] = self._counts.get(reason, 0) + count

    def total(self) -> int:
        return sum(self._counts.values())

    def counts(self) -> dict[str, int]:
        return {str(reason): n for reason, n in sorted(self._counts.items())}


def _reason_of(bad: mavlink2.MAVLink_bad_data) -> Drop:
    text = str(getattr(bad, "reason", ""))
    if "CRC" in text:
        return Drop.BAD_CRC
    if "prefix" in text:
        return Drop.BAD_PREFIX
    if "unknown MAVLink message" in text:
        return Drop.UNKNOWN_MESSAGE
    return Drop.MALFORMED


@dataclass
class _Peer:
    """One station: its parser, its allowance, when it was last heard."""

    parser: mavlink2.MAVLink = field(default_factory=lambda: _new_parser())
    tokens: float = PEER_BURST
    refilled_at: float = field(default_factory=time.monotonic)
    heard_at: float = field(default_factory=time.monotonic)
    station: bool = False
    heartbeat_at: float = 0.0
    #: The secret it signs with (signing: the first one that verified; never changes)
    key: StationKey | None = None

    def allow(self, now: float, spend: float = 1.0) -> bool:
        """Whether the peer may send one more message now (taking it from its share
        unless `spend` is 0: only looking)."""
        self.tokens = min(PEER_BURST, self.tokens + (now - self.refilled_at) * PEER_RATE_HZ)
        self.refilled_at = now
        if self.tokens < 1.0:
            return False
        self.tokens -= spend
        return True


def _new_parser() -> mavlink2.MAVLink:
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    return parser


Address = tuple[str, int]


@dataclass(frozen=True)
class Incoming:
    message: mavlink2.MAVLink_message
    peer: Address


def parse_url(url: str) -> tuple[str, Address]:
    """`udpout:127.0.0.1:14550` -> ("udpout", ("127.0.0.1", 14550))."""
    kind, _, rest = url.partition(":")
    host, _, port = rest.rpartition(":")
    if kind not in ("udpout", "udpin", "tcpin") or not host:
        raise EndpointError(
            f"{url!r}: expected udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT"
        )
    try:
        number = int(port)
    except ValueError:
        raise EndpointError(f"{url!r}: the port {port!r} is not a number") from None
    if not 0 <= number <= 65535:
        raise EndpointError(f"{url!r}: port out of range")
    return kind, (host, number)


class Endpoint:
    """The open endpoint. Used from one thread (the gateway's loop)."""

    def __init__(
        self,
        url: str,
        drops: InputDrops,
        clock: Callable[[], float] = time.monotonic,
        verifier: Verifier | None = None,
    ):
        self.kind, self.address = parse_url(url)
        self.drops = drops
        self._clock = clock
        self.verifier = verifier
        #: What is sent to a station whose secret is not known yet (the udpout address
        #: before it spoke) is signed with the first secret.
        self._default_key = verifier.keys[0] if verifier is not None else None
        self._selector = selectors.DefaultSelector()
        self._peers: dict[Address, _Peer] = {}
        self._tcp: dict[socket.socket, Address] = {}
        self._out_of_order: list[Incoming] = []
        try:
            if self.kind == "tcpin":
                self._sock = socket.create_server(self.address)
            else:
                self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                if self.kind == "udpin":
                    self._sock.bind(self.address)
                else:
                    self._sock.connect(self.address)
        except OSError as error:
            raise EndpointError(
                f"{url}: {error.strerror or error}{in_use_advice(error, '--out')}"
            ) from None
        self._sock.setblocking(False)
        self._selector.register(self._sock, selectors.EVENT_READ)
        if self.kind == "udpout":
            self._peers[self.address] = _Peer(
                station=True, heartbeat_at=clock(), refilled_at=clock()
            )

    @property
    def local_port(self) -> int:
        port: int = self._sock.getsockname()[1]
        return port

    @property
    def url(self) -> str:
        """Where it is: a station's address for udpout, else the address it listens on,
        with the port it bound (`tcpin:127.0.0.1:0` asks for any free one)."""
        if self.kind == "udpout":
            host, port = self.address
        else:
            host, port = self.address[0], self.local_port
        return f"{self.kind}:{host}:{port}"

    def close(self) -> None:
        for client in list(self._tcp):
            client.close()
        self._selector.close()
        self._sock.close()

    # ---- input ---------------------------------------------------------------------------
    def receive(self, timeout_s: float) -> list[Incoming]:
        """What came in within `timeout_s` (at most `READ_BUDGET` reads), decoded."""
        got: list[Incoming] = []
        reads = 0
        for key, _ in self._selector.select(timeout_s):
            sock = key.fileobj
            assert isinstance(sock, socket.socket)
            while reads < READ_BUDGET:
                reads += 1
                if sock is self._sock and self.kind == "tcpin":
                    self._accept()
                    break
                if not self._read(sock, got):
                    break
        self._forget_silent()
        return got

    def _accept(self) -> None:
        try:
            client, address = self._sock.accept()
        except BlockingIOError:
            return
        if self._pending_count() >= MAX_PENDING:
            # Idle connections cannot lock stations out: the oldest waiting one goes.
            oldest = self._oldest_pending()
            if oldest is None:
                client.close()
                return
            self._drop_client(next(c for c, a in self._tcp.items() if a == oldest))
            self.drops.add(Drop.NO_HEARTBEAT)
        client.setblocking(False)
        self._tcp[client] = address
        self._peers[address] = _Peer(heard_at=self._clock(), refilled_at=self._clock())
        self._selector.register(client, selectors.EVENT_READ)
        log.info("connection from %s:%d", *address)

    def _read(self, sock: socket.socket, got: list[Incoming]) -> bool:
        """One read from `sock`; False when there is nothing more to read now."""
        try:
            if sock in self._tcp:
                data, peer = sock.recv(_DATAGRAM), self._tcp[sock]
                if not data:
                    self._drop_client(sock)
                    return False
            else:
                data, peer = sock.recvfrom(_DATAGRAM)
        except (BlockingIOError, InterruptedError):
            return False
        except OSError as error:
            # udpout before anyone listens: ECONNREFUSED for our own last datagram.
            log.debug("receive: %s", error)
            if sock in self._tcp:
                self._drop_client(sock)
            return False
        self._decode(data, peer, stream=sock in self._tcp, got=got)
        return True

    def _drop_client(self, client: socket.socket) -> None:
        address = self._tcp.pop(client)
        self._peers.pop(address, None)
        self._selector.unregister(client)
        client.close()
        log.info("ground station %s:%d disconnected", *address)

    def _pending_count(self) -> int:
        return sum(1 for p in self._peers.values() if not p.station)

    def _oldest_pending(self) -> Address | None:
        waiting = [(p.heard_at, a) for a, p in self._peers.items() if not p.station]
        return min(waiting)[1] if waiting else None

    def _peer(self, address: Address) -> _Peer:
        peer = self._peers.get(address)
        if peer is None:
            if self._pending_count() >= MAX_PENDING:
                oldest = self._oldest_pending()
                if oldest is not None:
                    del self._peers[oldest]
            peer = self._peers[address] = _Peer(heard_at=self._clock(), refilled_at=self._clock())
            log.debug("datagram from %s:%d (a station once it sends a heartbeat)", *address)
        return peer

    def stations(self) -> int:
        return sum(1 for p in self._peers.values() if p.station)

    def _take(self, peer: _Peer, address: Address, message: mavlink2.MAVLink_message) -> bool:
        """Whether `message`, decoded from `peer`, is taken: signed as required, and from
        a station (its heartbeat making it one)."""
        now = self._clock()
        if self.verifier is not None:
            verdict, key = self.verifier.check(message, peer.key)
            if verdict is not Verdict.OK:
                self.drops.add(Drop(str(verdict)))
                return False
            peer.key = key
        if message.get_msgId() == mavlink2.MAVLINK_MSG_ID_HEARTBEAT:
            peer.heartbeat_at = now
            if not peer.station:
                if self.stations() >= MAX_STATIONS:
                    self.drops.add(Drop.TOO_MANY_PEERS)
                    return False
                peer.station = True
                signed = f", signed by {peer.key.name}" if peer.key is not None else ""
                log.info("ground station at %s:%d (its heartbeat%s)", *address[:2], signed)
        if not peer.station:
            self.drops.add(Drop.NO_HEARTBEAT)
            return False
        return True

    def _decode(self, data: bytes, address: Address, stream: bool, got: list[Incoming]) -> None:
        peer = self._peer(address)
        now = self._clock()
        peer.heard_at = now
        if not stream and not peer.allow(now, spend=0.0):
            # A station over its share: its datagram is dropped unread, so a flood costs
            # a read, not a parse per frame.
            self.drops.add(Drop.FLOOD)
            return
        try:
            messages = peer.parser.parse_buffer(data) or []
        except Exception as error:  # hostile bytes must never end the gateway
            log.debug("undecodable input from %s:%d: %s", *address, error)
            peer.parser = _new_parser()
            self.drops.add(Drop.MALFORMED)
            return
        if not stream and peer.parser.buf_len() > 0:
            # A datagram carries whole frames: what is left is a frame cut short.
            self.drops.add(Drop.TRUNCATED)
            peer.parser = _new_parser()
        for message in messages:
            if isinstance(message, mavlink2.MAVLink_bad_data):
                self.drops.add(_reason_of(message))
            elif isinstance(message, mavlink2.MAVLink_unknown):
                # A frame whose CRC cannot be checked (its id is in no dialect).
                self.drops.add(Drop.UNKNOWN_MESSAGE)
            elif not peer.allow(now):
                self.drops.add(Drop.FLOOD)
            elif self._take(peer, address, message):
                got.append(Incoming(message, address))

    def _forget_silent(self) -> None:
        """Let go of stations silent for `STATION_TTL_S` and of peers that waited
        `PENDING_TTL_S` for their heartbeat (never the udpout address)."""
        if self.kind == "udpout":
            return
        now = self._clock()
        silent = [
            address
            for address, peer in self._peers.items()
            if (peer.station and now - peer.heartbeat_at > STATION_TTL_S)
            or (not peer.station and now - peer.heard_at > PENDING_TTL_S)
        ]
        for address in silent:
            if self._peers[address].station:
                log.info("ground station at %s:%d silent: let go", *address[:2])
            if self.kind == "tcpin":
                self._drop_client(next(c for c, a in self._tcp.items() if a == address))
            else:
                del self._peers[address]

    # ---- output --------------------------------------------------------------------------
    def send(self, pack: Callable[[StationKey | None], bytes], to: Address | None = None) -> None:
        """To every station (the udpout address, each udpin or TCP station), or only to
        the station at `to`, packed by `pack` for the secret it signs with (None:
        unsigned); once per secret.

        Each station on its own: one that cannot be sent to (an address no datagram can
        reach, a client that reset) is dropped, never the stations after it."""
        packed: dict[str | None, bytes] = {}

        def data_for(peer: _Peer) -> bytes:
            key = peer.key or self._default_key
            name = key.name if key is not None else None
            if name not in packed:
                packed[name] = pack(key)
            return packed[name]

        if self.kind == "udpout":
            try:
                self._sock.send(data_for(self._peers[self.address]))
            except OSError as error:
                # Nobody listening yet (udpout): heartbeats go on until somebody does.
                log.debug("send: %s", error)
            return
        if self.kind == "udpin":
            for address, peer in list(self._peers.items()):
                if not peer.station or (to is not None and address != to):
                    continue
                try:
                    self._sock.sendto(data_for(peer), address)
                except OSError as error:
                    log.info("station %s:%d unreachable (%s): forgotten", *address[:2], error)
                    del self._peers[address]
            return
        for client, address in list(self._tcp.items()):
            found = self._peers.get(address)
            if found is None or not found.station or (to is not None and address != to):
                continue
            try:
                client.send(data_for(found))
            except BlockingIOError:
                log.debug("station %s:%d is slow: frame skipped", *address)
            except OSError as error:
                log.info("station %s:%d gone (%s)", *address, error)
                self._drop_client(client)
