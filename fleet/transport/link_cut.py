"""Closing one of this process's own TCP connections, found by its two addresses.

Zenoh's Python API lists a router's links (`Session.info.links()`: each with its local
and remote locator and the common name of the certificate the other end presented) but
has no call to close one. The connection is a socket of this very process, though: `cut`
finds the descriptor whose local and peer addresses are the link's and shuts the socket
down, both ways. Zenoh's reader then sees the connection end and closes the link and its
transport as it would for a peer gone away.

The socket is shut down through a duplicate of its descriptor, checked first: if Zenoh
closed the descriptor meanwhile and the number was reused, the duplicate names another
socket, its addresses do not match, and it is left alone. `shutdown` acts on the socket,
not the descriptor, and closes none, so Zenoh's own descriptor stays valid until Zenoh
closes it. Bytes the peer sent that Zenoh has not read yet are read and dropped, so none
of them is routed.

`cut_accepted` ends every connection still open on a closed listener's address: Zenoh
accepts a connection while its session closes and completes the handshake after the close
has closed the transports it knew, so that one transport outlives the session (its client
stays connected to a router that is gone; seen with a client redialling at that moment).

Stream sockets (tcp/, tls/) only: a datagram link (udp/, quic/) shares its socket with
others and is not cut. Descriptors are listed from /proc/self/fd (Linux) or /dev/fd.
"""

from __future__ import annotations

import ipaddress
import logging
import os
import socket
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

#: Where this process's open descriptors are listed, first found wins.
_FD_DIRS = (Path("/proc/self/fd"), Path("/dev/fd"))
#: Locator protocols carried on a stream socket of their own.
STREAM_PROTOCOLS = frozenset({"tcp", "tls", "ws"})
_DRAIN_CHUNK = 65_536
#: Bytes read and dropped at most per cut (a peer streaming faster is cut all the same).
_DRAIN_MAX = 16 * _DRAIN_CHUNK


@dataclass(frozen=True)
class Address:
    """A link's end as its locator names it: a host (an IP address, or a name a dialled
    locator kept) and a port."""

    host: str
    port: int

    def matches(self, address: tuple[str, int] | tuple[str, int, int, int]) -> bool:
        """Whether a socket address (`getsockname`, `getpeername`) is this one. A host
        that is a name, not an address, or the unspecified address a listener binds
        (`0.0.0.0`, `::`), is matched on the port alone."""
        host, port = address[0], address[1]
        if port != self.port:
            return False
        mine = _ip(self.host)
        return mine is None or mine.is_unspecified or mine == _ip(host)


def _ip(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        ip = ipaddress.ip_address(text.split("%", 1)[0])  # no IPv6 zone
    except ValueError:
        return None
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return ip.ipv4_mapped  # a dual-stack socket names an IPv4 peer so
    return ip


def address_of(locator: str) -> Address | None:
    """The address in a stream locator, `tls/127.0.0.1:7447` or `tcp/[::1]:7447` (any
    `?metadata` or `#config` after it ignored); None for another protocol or a malformed
    locator."""
    protocol, sep, rest = locator.partition("/")
    if not sep or protocol not in STREAM_PROTOCOLS:
        return None
    rest = rest.split("?", 1)[0].split("#", 1)[0]
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit():
        return None
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    return Address(host, int(port)) if host else None


def _descriptors() -> list[int]:
    for directory in _FD_DIRS:
        try:
            return [int(name) for name in os.listdir(directory) if name.isdigit()]
        except OSError:
            continue
    return []


def cut(local: Address, peer: Address) -> int:
    """Shut down every socket of this process from `local` to `peer` (both ways), drop
    what it received unread; how many were cut (0: none is open, or none can be listed)."""
    return _cut_where(lambda mine, theirs: local.matches(mine) and peer.matches(theirs))


def cut_accepted(local: Address) -> int:
    """Shut down every connected socket of this process on `local` (a listener's address,
    closed now), whatever its peer, as `cut` does; how many were cut."""
    return _cut_where(lambda mine, _theirs: local.matches(mine))


_SocketAddress = tuple[str, int] | tuple[str, int, int, int]


def _cut_where(matching: Callable[[_SocketAddress, _SocketAddress], bool]) -> int:
    cut_count = 0
    for fd in _descriptors():
        try:
            duplicate = os.dup(fd)
        except OSError:
            continue  # closed meanwhile
        try:
            sock = socket.socket(fileno=duplicate)
        except OSError:
            os.close(duplicate)  # not a socket
            continue
        with sock:  # closes the duplicate only
            if _cut_if_matching(sock, matching):
                cut_count += 1
    return cut_count


def _cut_if_matching(
    sock: socket.socket, matching: Callable[[_SocketAddress, _SocketAddress], bool]
) -> bool:
    if sock.type != socket.SOCK_STREAM or sock.family not in (socket.AF_INET, socket.AF_INET6):
        return False
    try:
        if not matching(sock.getsockname(), sock.getpeername()):
            return False
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        return False  # not connected (a listener), or already shut down
    _drain(sock)
    return True


def _drain(sock: socket.socket) -> None:
    """Read and drop what the peer sent that nobody read yet (bounded)."""
    sock.setblocking(False)  # shared with Zenoh's descriptor, which is non-blocking anyway
    drained = 0
    try:
        while drained < _DRAIN_MAX and (chunk := sock.recv(_DRAIN_CHUNK)):
            drained += len(chunk)
    except OSError:
        pass  # nothing more to read now
