"""Which Host a local server answers to: the DNS-rebinding check of the page and of the
Foxglove server (pure, no web framework).

A site the operator visits can point its own name at this machine's address; its
scripts then reach a local server as the same origin. A request naming a Host that is
neither the address the server is bound to nor `localhost` is such a page. A server
bound to every interface (`0.0.0.0`, `::`) cannot know its names: it allows any Host
and relies on its other checks (a token, the Origin).
"""

from __future__ import annotations

import ipaddress

_WILDCARDS = ("0.0.0.0", "::", "")
_LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


def is_loopback(host: str) -> bool:
    """`host` (a name or an address) is this machine only: `localhost` or a loopback
    address; any other name may resolve elsewhere."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def normal_host(host: str) -> str:
    """`[::1]`, `LOCALHOST.`, `127.000.0.1` -> the one spelling compared."""
    host = host.strip().lower().rstrip(".").removeprefix("[").removesuffix("]")
    try:
        return str(ipaddress.ip_address(host))
    except ValueError:
        return host


def host_of_header(value: str) -> str:
    """A Host header's host, without its port: `[::1]:8765` -> `::1`."""
    value = value.strip()
    if value.startswith("["):
        return value[1 : value.find("]")] if "]" in value else value
    return value.rpartition(":")[0] if value.count(":") == 1 else value


class HostAllowList:
    def __init__(self, bound_host: str) -> None:
        bound = normal_host(bound_host)
        self.any_host = bound in _WILDCARDS
        # A loopback address typed as such is no rebinding (that needs a foreign name).
        loopback = set(_LOOPBACK_NAMES) if bound in _LOOPBACK_NAMES else set()
        self.hosts = frozenset({bound, "localhost", *loopback})

    def allowed(self, host: str | None) -> bool:
        """Whether a request naming `host` (no port) is answered."""
        return self.any_host or (host is not None and normal_host(host) in self.hosts)
