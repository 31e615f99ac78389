"""A secure fleet of real processes for an end-to-end test: a router with mutual TLS and
access control, the simulated autopilots of `head_on`, onboards 74 and 112, and a raw
Zenoh session as the ground to ask the UAVs' states (signed, and answered by each UAV
alone: a teammate relays a UAV's state only to a query that asks for relays, and only
as that UAV signed it)."""

from __future__ import annotations

import contextlib
import json
import subprocess
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import zenoh

from fleet.files.certs import write_identities
from fleet.files.signers import revoke
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import UavState
from fleet.transport.bus_codec import decode
from fleet.transport.zenoh_config import build_config
from tests.support import secure_clients
from tests.support.processes import Child, Fleet, start_fleet_up, start_router
from tests.support.waiting import wait_until

SPACE = KeySpace()
TARGETS_FILE = str(files("fleet") / "scenarios" / "head_on_targets.bin")


@dataclass
class SignedFleet:
    endpoint: str
    certs: Path
    fleet: Fleet
    ground: zenoh.Session

    def session(self, identity: str) -> zenoh.Session:
        return secure_clients.session(self.certs, self.endpoint, identity)

    def ground_cli(self, *argv: str) -> subprocess.CompletedProcess[str]:
        return secure_clients.ground_cli(self.certs, self.endpoint, *argv)

    def state(self, uav: int) -> UavState | None:
        for reply in self.ground.get(SPACE.state(uav), timeout=5.0):
            if reply.ok is not None:
                return decode(reply.ok.payload.to_bytes(), UavState, SPACE.state(uav))
        return None

    def refused(self, uav: int, reason: str) -> int:
        """How many messages `uav` refused for `reason` (its state's link drops)."""
        state = self.state(uav)
        return state.link.drops.get(f"bus_{reason}", 0) if state and state.link else 0

    def send_targets(self, *argv: str) -> int:
        sent = self.ground_cli("send-targets", TARGETS_FILE, "--json", *argv)
        assert sent.returncode == 0, sent.stderr[-3000:]
        mission = json.loads(sent.stdout)["mission"]
        assert isinstance(mission, int)
        wait_until(lambda: mission_of(self.state(112)) == mission, 30.0, f"112 on {mission}")
        return mission


def mission_of(state: UavState | None) -> int | None:
    return state.mission.mission if state and state.mission else None


def open_when_listening(config_file: Path, endpoint: str) -> zenoh.Session:
    deadline = time.monotonic() + 30.0
    while True:
        try:
            return zenoh.open(build_config(config_file=str(config_file), connect=[endpoint]))
        except zenoh.ZError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)  # the router is starting: poll, bounded


#: The secure profile's router on loopback, on a port the OS picks (the certificates name
#: the host alone; every client is given the port bound).
ANY_TLS_PORT = "tls/127.0.0.1:0"


def start_secure_up(certs: Path, *extra: str) -> Child:
    """`fleet up head_on --secure` at five times real time, logging under `certs`, with
    the identities of a router, the ground and UAVs 74 and 112 made in `certs` for a
    loopback tls/ endpoint on a free port, and `extra` arguments (its banner says which
    port: `wait_fleet_up`)."""
    write_identities(certs, ["router", "ground", "uav-74", "uav-112"], [ANY_TLS_PORT])
    return start_fleet_up(
        "head_on", "--secure", str(certs), "--listen", ANY_TLS_PORT, "--speedup", "5",
        "--log-dir", str(certs / "logs"), *extra,
    )  # fmt: skip


@contextlib.contextmanager
def signed_fleet(
    certs: Path,
    names: list[str],
    *router_argv: str,
    speedup: float = 5.0,
    revoked: Sequence[str] = (),
    onboard_argv: Mapping[int, Sequence[str]] | None = None,
) -> Iterator[SignedFleet]:
    """Identities `names` made in `certs` (with `router`, `ground`, `uav-74`, `uav-112`),
    those `revoked` withdrawn (`fleet certs revoke`), a secure router (`router_argv` added
    to its command line) and the fleet (each onboard's command line with its
    `onboard_argv`, if any)."""
    write_identities(certs, names, [ANY_TLS_PORT])
    if revoked:
        revoke(certs, list(revoked))
    fleet = Fleet()
    try:
        router, endpoint = start_router(
            "--secure", str(certs), "--listen", ANY_TLS_PORT, *router_argv
        )
        fleet.children.append(router)
        ground = open_when_listening(certs / "ground.json5", endpoint)
        try:
            for uav, where in fleet.sim("head_on", speedup=speedup).items():
                config = str(certs / f"uav-{uav}.json5")
                extra = (onboard_argv or {}).get(uav, ())
                fleet.onboard(uav, where, endpoint, "--zenoh-config", config, *extra)
            secure = SignedFleet(endpoint, certs, fleet, ground)
            wait_until(lambda: secure.state(74) and secure.state(112), 60.0, "both onboards up")
            yield secure
        finally:
            ground.close()
    finally:
        fleet.stop_all()
