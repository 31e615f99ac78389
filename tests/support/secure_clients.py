"""Clients of a secure fleet (`fleet certs make`, a router on a tls/ endpoint), as a
given identity: a raw Zenoh session, or `ground-cli` as the ground."""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

import zenoh

from fleet.transport.zenoh_config import build_config
from tests.support import ground_cli as support_cli

GROUND_CLI_TIMEOUT_S = 120


def session(certs: Path, endpoint: str, identity: str) -> zenoh.Session:
    """A Zenoh client session presenting `identity`'s certificate, connected to `endpoint`."""
    config = build_config(config_file=str(certs / f"{identity}.json5"), connect=[endpoint])
    return zenoh.open(config)


def ground_cli(certs: Path, endpoint: str, *argv: str) -> subprocess.CompletedProcess[str]:
    """`ground-cli ARGV` as the ground, waited for (bounded)."""
    return support_cli.ground_cli(
        "--zenoh-config", str(certs / "ground.json5"), *argv,
        connect=endpoint, timeout=GROUND_CLI_TIMEOUT_S,
    )  # fmt: skip


@dataclass
class SecureEndpoint:
    """A secure fleet's router endpoint and the folder of its identities: what a client
    needs to join it as one of them."""

    endpoint: str
    certs: Path

    def session(self, identity: str) -> zenoh.Session:
        return session(self.certs, self.endpoint, identity)

    def ground_cli(self, *argv: str) -> subprocess.CompletedProcess[str]:
        return ground_cli(self.certs, self.endpoint, *argv)
