"""Zenoh session configuration shared by every fleet process.

Multicast scouting is off everywhere: it is slow or broken in containers and CI, so
peers are always named by explicit tcp endpoints. The scouting delay is 0 so a
router-mode session opens in milliseconds rather than 500 ms.

Shared memory is off too (`SHARED_MEMORY_OFF`). Zenoh's default turns it on lazily: the
first message over 3 KB a process sends (a 50-target mission, a UAV's state with its
mission) makes it create a 16 MiB pool and map its peers' pools, which put 20-35 MB
resident in every such process (fifty onboards on one box). Fleet messages are
small, and the aircraft of a real fleet share no memory.

A deployment that needs more (TLS, access control, shared memory, timeouts) gives a full
Zenoh JSON5 config file instead, as zenoh's own tools and rmw_zenoh do: `build_config`
loads it and lays only the endpoints and mode named on the command line over it.
"""

from __future__ import annotations

import json
import os
import re

import zenoh

from fleet.errors import FleetError

DEFAULT_ROUTER = "tcp/127.0.0.1:7447"
CONNECT_ENV = "FLEET_ZENOH_CONNECT"
#: A full Zenoh config file (JSON5, JSON or YAML) to use instead of the built-in one.
CONFIG_ENV = "FLEET_ZENOH_CONFIG"
MODES = ("client", "peer", "router")
#: The config key and value that keep Zenoh's shared-memory transport off.
SHARED_MEMORY_OFF = ("transport/shared_memory/enabled", "false")

# `proto/address`, e.g. tcp/127.0.0.1:7447 or tcp/[::1]:7447; Zenoh checks the rest.
_ENDPOINT = re.compile(r"^[a-z0-9]+/\S+$")


class ZenohConfigError(FleetError, ValueError):
    """A Zenoh config file, endpoint or mode is unusable; the message says which and why."""


def default_connect() -> str:
    """The router to connect to: $FLEET_ZENOH_CONNECT, else the local fleet's router."""
    return os.environ.get(CONNECT_ENV, DEFAULT_ROUTER)


#: Where in Zenoh's Rust source an error was made: nothing a user can act on.
_RUST_LOCATION = re.compile(r"\s+at \S+\.rs:\d+\.?")


def error_text(error: BaseException) -> str:
    """A Zenoh error's first line, without the Rust source locations Zenoh appends (one
    per error it wraps: "... [127.0.0.1:7447: Address already in use (os error 98) at
    /root/.cargo/.../tcp.rs:61.] at /root/.cargo/.../unicast.rs:338.")."""
    text = str(error).strip()
    first = text.splitlines()[0] if text else type(error).__name__
    first = _RUST_LOCATION.sub("", first)
    return first.replace("[", "(").replace("]", ")").rstrip(". ").strip()


def check_endpoint(endpoint: str) -> str:
    """`endpoint` if it reads PROTO/ADDRESS; raises ZenohConfigError otherwise."""
    if not _ENDPOINT.match(endpoint):
        raise ZenohConfigError(
            f"malformed Zenoh endpoint {endpoint!r}: expected PROTO/ADDRESS, "
            "e.g. tcp/127.0.0.1:7447"
        )
    return endpoint


def make_config(
    mode: str = "client",
    connect: list[str] | None = None,
    listen: list[str] | None = None,
) -> zenoh.Config:
    """The built-in configuration: `mode`, explicit endpoints, no multicast scouting."""
    if mode not in MODES:
        raise ZenohConfigError(f"zenoh mode {mode!r}: expected one of {', '.join(MODES)}")
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/delay", "0")
    config.insert_json5(*SHARED_MEMORY_OFF)
    _set_endpoints(config, connect, listen)
    if mode == "router":
        # Let stock tools read the router's admin space (`@/**`).
        config.insert_json5("adminspace/enabled", "true")
    return config


def load_config(path: str) -> zenoh.Config:
    """A full Zenoh config from `path`; raises ZenohConfigError naming the file and the fault."""
    try:
        with open(path, "rb"):
            pass
    except OSError as error:
        raise ZenohConfigError(
            f"cannot read Zenoh config {path}: {error.strerror or error}"
        ) from None
    try:
        return zenoh.Config.from_file(path)
    except zenoh.ZError as error:
        raise ZenohConfigError(f"Zenoh config {path} is not valid: {error_text(error)}") from None


def build_config(
    mode: str | None = None,
    connect: list[str] | None = None,
    listen: list[str] | None = None,
    config_file: str | None = None,
) -> zenoh.Config:
    """The session configuration a command line asks for.

    Without `config_file`: `make_config` in `mode` (client by default), a client
    connecting to `default_connect()` unless `connect` names endpoints. With it: the
    file, with `mode`, `connect` and `listen` (when given) replacing the file's values;
    $FLEET_ZENOH_CONNECT, when set and `connect` is not given, replaces the file's
    endpoints too (the secure profile's `export` lines name the router's real port, which
    a copied config file may not).
    """
    if config_file is not None and not connect and os.environ.get(CONNECT_ENV):
        connect = [os.environ[CONNECT_ENV]]
    for endpoint in (*(connect or ()), *(listen or ())):
        check_endpoint(endpoint)
    if config_file is None:
        mode = mode or "client"
        if not connect and mode == "client":
            connect = [check_endpoint(default_connect())]
        return make_config(mode, connect, listen)
    config = load_config(config_file)
    if mode is not None:
        if mode not in MODES:
            raise ZenohConfigError(f"zenoh mode {mode!r}: expected one of {', '.join(MODES)}")
        config.insert_json5("mode", json.dumps(mode))
    _set_endpoints(config, connect, listen)
    return config


def endpoints(config: zenoh.Config, which: str = "connect") -> list[str]:
    """The `connect` (or `listen`) endpoints a config names (for messages)."""
    try:
        value = json.loads(config.get_json(f"{which}/endpoints"))
    except (zenoh.ZError, ValueError):
        return []
    # A mode-dependent value is a {router: [...], peer: [...], client: [...]} table.
    if isinstance(value, dict):
        mode = json.loads(config.get_json("mode") or '"peer"')
        value = value.get(mode, [])
    return [str(endpoint) for endpoint in value] if isinstance(value, list) else []


def _set_endpoints(
    config: zenoh.Config, connect: list[str] | None, listen: list[str] | None
) -> None:
    try:
        if connect:
            config.insert_json5("connect/endpoints", json.dumps(connect))
        if listen:
            config.insert_json5("listen/endpoints", json.dumps(listen))
    except zenoh.ZError as error:
        raise ZenohConfigError(f"bad Zenoh endpoint: {error_text(error)}") from None


def has_tls_identity(config: zenoh.Config) -> bool:
    """Whether `config` names a CA and a certificate of its own (a TLS client identity):
    the one case where the bus may sign (fleet.transport.signing decides the rest)."""
    try:
        tls = json.loads(config.get_json("transport/link/tls"))
    except (zenoh.ZError, TypeError, ValueError):
        return False
    return (
        isinstance(tls, dict)
        and isinstance(tls.get("root_ca_certificate"), str)
        and isinstance(tls.get("connect_certificate"), str)
    )


def uses_mtls(config: zenoh.Config) -> bool:
    """Whether `config` is the secure profile's: mutual TLS with an identity of its own."""
    try:
        tls = json.loads(config.get_json("transport/link/tls"))
    except (zenoh.ZError, ValueError):
        return False
    return isinstance(tls, dict) and tls.get("enable_mtls") is True
