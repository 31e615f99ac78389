"""The Foxglove server's front door: a Host and an Origin allow-list.

The Foxglove WebSocket protocol has no access control of its own, and the SDK's server
checks neither the Host nor the Origin of a handshake: any web page open in the
operator's browser could open `ws://127.0.0.1:8765` and read the fleet's positions and
states (a browser sends its page's Origin with every WebSocket handshake, and lets any
site connect to any address), or reach it by DNS rebinding. So `fleet foxglove` serves
clients through this gate:

* the handshake's `Host` must be the address the gate is bound to, `localhost`, or a
  name given with `--allow-host` (`ground.host_check`);
* its `Origin`, when it has one (a browser always sends it; Foxglove's own clients and
  scripts need not), must be allowed: Foxglove's web app (`https://app.foxglove.dev`),
  `file://` (pages loaded from files, as an Electron app's), or one given with
  `--allow-origin`;
* anything else is answered 403 with the reason, counted and logged (rate-limited).

An accepted connection is passed on, byte for byte, to the SDK's server, which listens
on a loopback port of its own with TLS under a certificate made for this run and
trusted by the gate alone: a web page that finds that port cannot complete a handshake
with it (its browser refuses the certificate, and `ws://` is no TLS).
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime
import ipaddress
import logging
import ssl
import threading
from collections import Counter
from dataclasses import dataclass

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from fleet.transport.refusal_log import RefusalLog
from ground.host_check import HostAllowList, host_of_header

log = logging.getLogger(__name__)

#: Origins allowed by default: Foxglove's web app, and pages loaded from files.
DEFAULT_ORIGINS = ("https://app.foxglove.dev", "file://")
#: A handshake's head at most, and how long a client may take to send it.
MAX_HEAD = 16_384
HEAD_TIMEOUT_S = 10.0
#: Connections open at once at most (a Foxglove client holds one).
MAX_CLIENTS = 64
_LOOPBACK = "127.0.0.1"


def normal_origin(origin: str) -> str:
    return origin.strip().lower().rstrip("/")


@dataclass(frozen=True)
class Rules:
    """What the gate lets through."""

    hosts: HostAllowList
    extra_hosts: frozenset[str]
    origins: frozenset[str]

    @classmethod
    def make(cls, bound_host: str, allow_hosts: list[str], allow_origins: list[str]) -> Rules:
        return cls(
            HostAllowList(bound_host),
            frozenset(h.strip().lower().rstrip(".") for h in allow_hosts),
            frozenset(normal_origin(o) for o in (*DEFAULT_ORIGINS, *allow_origins)),
        )

    def refusal(self, head: bytes) -> str | None:
        """Why a handshake whose head (request line and headers) is `head` is refused;
        None if it may pass."""
        lines = head.decode("latin-1").split("\r\n")
        if not lines[0].startswith("GET "):
            return "not a WebSocket handshake"
        headers: dict[str, list[str]] = {}
        for line in lines[1:]:
            name, sep, value = line.partition(":")
            if sep:
                headers.setdefault(name.strip().lower(), []).append(value.strip())
        hosts = headers.get("host", [])
        if len(hosts) != 1:
            return "no Host, or more than one"
        host = host_of_header(hosts[0])
        if not (self.hosts.allowed(host) or host.lower().rstrip(".") in self.extra_hosts):
            return f"host {hosts[0]!r} refused"
        origins = headers.get("origin", [])
        if len(origins) > 1:
            return "more than one Origin"
        if origins and normal_origin(origins[0]) not in self.origins:
            return f"origin {origins[0]!r} refused"
        return None


def upstream_identity() -> tuple[bytes, bytes]:
    """A certificate and key (PEM) for the SDK's server on loopback, made for this run."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "fleet foxglove (loopback)")])
    now = datetime.datetime.now(datetime.UTC)
    certificate = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(hours=1))
        .not_valid_after(now + datetime.timedelta(days=365))
        .add_extension(
            x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address(_LOOPBACK))]),
            critical=False,
        )
        .sign(key, hashes.SHA256())
    )
    key_pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    return certificate.public_bytes(serialization.Encoding.PEM), key_pem


class Gate:
    """Listens on (host, port); passes allowed handshakes on to the TLS server on
    loopback port `upstream_port`, whose certificate is `upstream_pem`.

    `start()` binds (OSError if it cannot) and serves on a thread of its own; `stop()`
    closes every connection."""

    def __init__(
        self, host: str, port: int, rules: Rules, upstream_port: int, upstream_pem: bytes
    ) -> None:
        self._address = (host, port)
        self.rules = rules
        self._upstream_port = upstream_port
        self._tls = ssl.create_default_context(cadata=upstream_pem.decode())
        self.refused: Counter[str] = Counter()
        self.passed = 0
        self._refusals = RefusalLog(log)
        self._writers: set[asyncio.StreamWriter] = set()  #: both ends of every connection
        self._loop = asyncio.new_event_loop()
        self._server: asyncio.Server | None = None
        self._thread = threading.Thread(target=self._loop.run_forever, name="foxglove-gate")
        self.port = port

    def start(self) -> None:
        host, port = self._address
        self._server = self._loop.run_until_complete(
            asyncio.start_server(self._client, host, port, limit=MAX_HEAD)
        )
        self.port = self._server.sockets[0].getsockname()[1]
        self._thread.start()

    def stop(self) -> None:
        if self._server is None:
            return
        server = self._server

        async def close() -> None:
            server.close()
            # Every connection's handler ends (closing both its ends) before the loop does.
            tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            await server.wait_closed()

        try:
            asyncio.run_coroutine_threadsafe(close(), self._loop).result(10.0)
        except (TimeoutError, RuntimeError) as error:
            log.warning("closing the gate's connections: %s", error)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10.0)
        self._loop.close()
        self._server = None

    def _refuse(self, peer: object, kind: str, reason: str) -> None:
        self.refused[kind] += 1
        self._refusals.warn(
            f"refused a Foxglove client from {peer}: {reason} ({sum(self.refused.values())} in all)"
        )

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = writer.get_extra_info("peername")
        if len(self._writers) >= 2 * MAX_CLIENTS:
            self._refuse(peer, "too_many", f"{MAX_CLIENTS} connections open already")
            writer.close()
            return
        self._writers.add(writer)
        try:
            await self._serve(reader, writer, peer)
        except asyncio.CancelledError:
            # Stopping: the connection ends here (asyncio's stream callback would
            # otherwise report the cancellation as an error of its own).
            pass
        finally:
            self._writers.discard(writer)
            writer.close()

    async def _serve(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, peer: object
    ) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT_S)
        except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError):
            self._refuse(peer, "malformed", "no complete handshake")
            return
        except OSError:
            return
        reason = self.rules.refusal(head)
        if reason is not None:
            self._refuse(peer, "origin" if reason.startswith("origin") else "host", reason)
            body = (reason + "\n").encode()
            writer.write(
                b"HTTP/1.1 403 Forbidden\r\nContent-Type: text/plain\r\nConnection: close\r\n"
                + f"Content-Length: {len(body)}\r\n\r\n".encode()
                + body
            )
            with contextlib.suppress(OSError):
                await writer.drain()
            return
        try:
            up_reader, up_writer = await asyncio.open_connection(
                _LOOPBACK, self._upstream_port, ssl=self._tls, server_hostname=_LOOPBACK
            )
        except OSError as error:
            log.error("the Foxglove server on loopback cannot be reached: %s", error)
            return
        self.passed += 1
        self._writers.add(up_writer)
        up_writer.write(head)
        pipes = [
            asyncio.create_task(_pipe(reader, up_writer)),
            asyncio.create_task(_pipe(up_reader, writer)),
        ]
        try:
            await asyncio.wait(pipes, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for pipe in pipes:
                pipe.cancel()
            await asyncio.gather(*pipes, return_exceptions=True)
            self._writers.discard(up_writer)
            up_writer.close()


async def _pipe(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    try:
        while data := await reader.read(65_536):
            writer.write(data)
            await writer.drain()
    except OSError:
        pass
