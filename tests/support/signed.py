"""Signing as a fleet identity in the tests and benchmarks: what a holder of its signing
key can send from a raw Zenoh session (`fleet.mission.signature`), its `BusSigning`, a bus
that signs as it, and a router with identities to sign as."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import zenoh

from fleet.files.certs import write_identities
from fleet.files.signers import load_roster, load_signing_key, signing_key_path
from fleet.mission.signature import sign
from fleet.transport.router import Router
from fleet.transport.signing import BusSigning
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import make_config
from tests.support.processes import ANY_PORT


def attachment(certs: Path, identity: str, key: str, payload: bytes) -> bytes:
    """The envelope `identity` (with its key from `certs`) puts on `payload` at `key` now."""
    signing_key = load_signing_key(signing_key_path(certs, identity))
    return sign(signing_key, identity, key, payload, time.time_ns())


def bus_signing(
    certs: Path,
    identity: str,
    *,
    clock: Callable[[], int] = time.time_ns,
    ca_pem: Path | None = None,
) -> BusSigning:
    """Signing and checking as `identity`: its key and the roster, from `certs`."""
    key = load_signing_key(signing_key_path(certs, identity))
    return BusSigning(identity, key, load_roster(certs), clock=clock, ca_pem=ca_pem)


def signing_bus(certs: Path, endpoint: str, identity: str) -> ZenohBus:
    """A client of the router at `endpoint` that signs and checks as `identity`, with the
    secure profile's stream checks (a bus opened with the secure config has them; here
    without TLS, which is the router's business)."""
    session = zenoh.open(make_config("client", [endpoint]))
    return ZenohBus(session, bus_signing(certs, identity))


@contextmanager
def buses_of(
    names: Iterable[str], open_bus: Callable[[str], ZenohBus]
) -> Iterator[dict[str, ZenohBus]]:
    """A bus for each identity of `names`, opened by `open_bus`; all closed on leaving."""
    made = {name: open_bus(name) for name in names}
    try:
        yield made
    finally:
        for bus in made.values():
            bus.close()


@contextmanager
def router_and_identities(names: Iterable[str]) -> Iterator[tuple[str, Path]]:
    """A plain router of this process on a port it chose, and the identities of `names`
    (naming no endpoint) in a temporary folder: its endpoint, and that folder."""
    with tempfile.TemporaryDirectory() as directory, Router([ANY_PORT]) as router:
        certs = Path(directory)
        write_identities(certs, list(names), [])
        yield router.endpoints[0], certs
