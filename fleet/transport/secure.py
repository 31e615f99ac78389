"""The secure profile: a router on `tls/` endpoints with mutual TLS and access control.

The fleet's identities (`fleet certs make DIR ...`) are the profile: the router presents
`DIR/router.pem` (a UAV's own router in a router-per-UAV mesh: `DIR/router-N.pem`),
accepts only clients with a certificate signed by `DIR/ca.pem`, and
enforces the access policy (`fleet.mission.access`) for exactly the UAVs that have an
identity in DIR (`DIR/uav-N.pem`) and are not revoked in its roster (`signers.json`).
Each client uses its own `DIR/NAME.json5`.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, replace
from pathlib import Path

import zenoh
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from fleet.files.certs import CertError, IdentityFiles, tls_settings
from fleet.files.signers import (
    ROSTER_FILE,
    RosterError,
    load_signing_key,
    revoked_identities,
    signing_key_path,
)
from fleet.mission.access import GROUND, ROUTER, Grant, fleet_policy, uav_identity
from fleet.mission.key_space import DEFAULT_SPACE, KeySpace
from fleet.transport.acl import access_control

_UAV_CERT = re.compile(r"^uav-(\d+)\.pem$")


@dataclass(frozen=True)
class SecureProfile:
    directory: Path
    uav_ids: tuple[int, ...]
    #: The keys the access policy covers.
    key_space: KeySpace = DEFAULT_SPACE
    #: The identity the router presents: the ground's router, or a UAV's own.
    router_name: str = ROUTER
    #: Identities withdrawn by the roster (`fleet certs revoke`): granted nothing.
    revoked: frozenset[str] = frozenset()

    @classmethod
    def load(
        cls, directory: Path, key_space: KeySpace = DEFAULT_SPACE, router_name: str = ROUTER
    ) -> SecureProfile:
        """The profile of the identities in `directory`, its policy on the keys of
        `key_space`, for the router presenting `router_name`; CertError names what is
        missing."""
        directory = directory.resolve()
        if not directory.is_dir():
            raise CertError(f"{directory}: no such directory (make it with `fleet certs make`)")
        uav_ids = sorted(
            int(match[1]) for path in directory.iterdir() if (match := _UAV_CERT.match(path.name))
        )
        try:
            revoked = revoked_identities(directory)
        except RosterError as error:
            raise CertError(str(error)) from None
        uav_ids = [u for u in uav_ids if uav_identity(u) not in revoked]
        profile = cls(directory, tuple(uav_ids), key_space, router_name, revoked)
        profile.identity(router_name).check()
        return profile

    def signing_key(self) -> Ed25519PrivateKey | None:
        """The router identity's own signing key (what it answers for itself is signed),
        or None for identities made before signed messages (no roster)."""
        if not (self.directory / ROSTER_FILE).is_file():
            return None
        try:
            return load_signing_key(signing_key_path(self.directory, self.router_name))
        except RosterError as error:
            raise CertError(str(error)) from None

    def identity(self, name: str) -> IdentityFiles:
        return IdentityFiles(self.directory, name)

    def uav_config(self, uav_id: int) -> Path:
        """UAV `uav_id`'s client config; CertError if it has no identity here."""
        files = self.identity(uav_identity(uav_id))
        files.check()
        return files.client_config

    def ground_config(self) -> Path:
        files = self.identity(GROUND)
        files.check()
        return files.client_config

    def apply_to_router(self, config: zenoh.Config) -> None:
        """Make `config` a secure router's: mTLS with the router's identity, and the ACL."""
        tls = tls_settings(self.identity(self.router_name))
        config.insert_json5("transport/link/tls", json.dumps(tls))
        policy = _without(
            fleet_policy(list(self.uav_ids), self.key_space, own=self.router_name), self.revoked
        )
        config.insert_json5("access_control", json.dumps(access_control(policy)))


def _without(grants: list[Grant], revoked: frozenset[str]) -> list[Grant]:
    """`grants` with no `revoked` subject: the ACL denies a revoked identity everything."""
    kept = [replace(g, subjects=tuple(s for s in g.subjects if s not in revoked)) for g in grants]
    return [grant for grant in kept if grant.subjects]
