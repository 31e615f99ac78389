"""The fleet's signing keys on disk: one Ed25519 key per identity, and the roster.

`fleet certs make` writes, beside each identity's TLS files, `DIR/NAME.sign` (its
Ed25519 private key, readable by its owner only) and one public `DIR/signers.json`:
every identity's public key and the identities withdrawn (`revoked`), signed by the
fleet's CA (`ca.key`, ECDSA P-256 over SHA-256), so a process that holds only `ca.pem`
believes no roster the operator did not sign. `fleet certs revoke DIR NAME` withdraws an
identity: it is listed as revoked and the roster signed again (the CA key is needed);
every process loads the roster when it starts, and the router's ACL leaves it out.

A process needs only its own `NAME.sign`, `signers.json` and `ca.pem`
(`fleet.mission.signature` says what is signed and checked).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from fleet.errors import RosterError as RosterError  # raised here, defined where it is light
from fleet.files.owned_files import check_directory, read_own, write_new
from fleet.mission.signature import Roster

ROSTER_FILE = "signers.json"
SIGNING_SUFFIX = ".sign"
CA_NAME = "ca"  #: as fleet.files.certs names the CA's files
#: A roster is small (a key per identity); anything much bigger is not one.
MAX_ROSTER_BYTES = 1 << 20


def signing_key_path(directory: Path, name: str) -> Path:
    return directory / f"{name}{SIGNING_SUFFIX}"


def _write_private(path: Path, data: bytes) -> None:
    # A new owner-only file: never through a symlink, never into a planted hard link.
    write_new(path, data, RosterError, private=True)


def _canonical(signers: dict[str, str], revoked: list[str]) -> bytes:
    body = {"signers": dict(sorted(signers.items())), "revoked": sorted(set(revoked))}
    return json.dumps(body, sort_keys=True, separators=(",", ":")).encode()


def _public_hex(key: Ed25519PublicKey) -> str:
    return key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw).hex()


def _write_roster(
    directory: Path, signers: dict[str, str], revoked: list[str], ca_key: ec.EllipticCurvePrivateKey
) -> None:
    body = _canonical(signers, revoked)
    signature = ca_key.sign(body, ec.ECDSA(hashes.SHA256()))
    document = {**json.loads(body), "signature": signature.hex()}
    # A new file, never written through a planted link.
    text = json.dumps(document, indent=2) + "\n"
    write_new(directory / ROSTER_FILE, text.encode(), RosterError)


def write_signers(directory: Path, names: list[str], ca_key: ec.EllipticCurvePrivateKey) -> None:
    """A new signing key for each of `names`, and the roster of them signed by `ca_key`."""
    signers: dict[str, str] = {}
    for name in names:
        key = Ed25519PrivateKey.generate()
        pem = key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
        _write_private(signing_key_path(directory, name), pem)
        signers[name] = _public_hex(key.public_key())
    _write_roster(directory, signers, [], ca_key)


def _read_roster(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as f:
            data = f.read(MAX_ROSTER_BYTES + 1)
        if len(data) > MAX_ROSTER_BYTES:
            raise ValueError("too large")
        document = json.loads(data)
        if not isinstance(document, dict):
            raise ValueError("not a JSON object")
        return document
    except (OSError, ValueError, RecursionError) as error:
        raise RosterError(f"{path}: not a readable roster of signers: {error}") from None


def load_roster(directory: Path, ca_pem: Path | None = None) -> Roster:
    """The roster in `directory`, checked against the CA in `ca_pem` (default
    `directory/ca.pem`); RosterError names the file and what is wrong."""
    path = directory / ROSTER_FILE
    return roster_of(_read_roster(path), ca_pem or directory / f"{CA_NAME}.pem", str(path))


def roster_document(directory: Path) -> bytes:
    """The roster file's bytes as written (what `fleet certs revoke` puts to the fleet)."""
    return json.dumps(_read_roster(directory / ROSTER_FILE)).encode()


def roster_of(document: dict[str, Any], ca_pem: Path, source: str) -> Roster:
    """The roster `document` says, if the CA in `ca_pem` signed it; RosterError names
    `source` (a file, or the key it was heard on) and what is wrong."""
    try:
        signers = document["signers"]
        revoked = document["revoked"]
        signature = bytes.fromhex(document["signature"])
        if not isinstance(signers, dict) or not isinstance(revoked, list):
            raise TypeError("signers must be an object, revoked a list")
        keys = {
            str(name): Ed25519PublicKey.from_public_bytes(bytes.fromhex(value))
            for name, value in signers.items()
        }
        body = _canonical({str(k): str(v) for k, v in signers.items()}, [str(r) for r in revoked])
    except (KeyError, TypeError, ValueError) as error:
        raise RosterError(f"{source}: malformed roster: {error}") from None
    try:
        authority = x509.load_pem_x509_certificate(ca_pem.read_bytes()).public_key()
    except (OSError, ValueError) as error:
        raise RosterError(f"{ca_pem}: not a readable CA certificate: {error}") from None
    if not isinstance(authority, ec.EllipticCurvePublicKey):
        raise RosterError(f"{ca_pem}: not the fleet's (ECDSA) CA")
    try:
        authority.verify(signature, body, ec.ECDSA(hashes.SHA256()))
    except InvalidSignature:
        raise RosterError(f"{source}: not signed by the CA in {ca_pem}") from None
    return Roster(keys, frozenset(str(r) for r in revoked))


def load_signing_key(path: Path) -> Ed25519PrivateKey:
    try:
        key = serialization.load_pem_private_key(path.read_bytes(), password=None)
    except (OSError, ValueError, TypeError) as error:
        raise RosterError(f"{path}: not a readable signing key: {error}") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise RosterError(f"{path}: not an Ed25519 signing key")
    return key


def _ca_key(directory: Path) -> ec.EllipticCurvePrivateKey:
    path = directory / f"{CA_NAME}.key"
    try:
        data = read_own(path, RosterError)
        key = serialization.load_pem_private_key(data, password=None)
    except (RosterError, ValueError, TypeError) as error:
        raise RosterError(f"{path}: the CA key is needed to sign the roster: {error}") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise RosterError(f"{path}: not the fleet's (ECDSA) CA key")
    return key


def revoked_identities(directory: Path) -> frozenset[str]:
    """The identities the roster in `directory` withdraws; none without a roster (made
    before signed commands), RosterError if there is one that cannot be believed."""
    if not (directory / ROSTER_FILE).exists():
        return frozenset()
    return load_roster(directory).revoked


def revoke(directory: Path, names: list[str]) -> Roster:
    """Withdraw `names`: list them as revoked in the roster, signed again by the CA,
    in a directory no other user can change (`owned_files`)."""
    check_directory(directory.resolve(), RosterError)
    roster = load_roster(directory)
    unknown = [n for n in names if n not in roster.keys]
    if unknown:
        raise RosterError(f"{directory / ROSTER_FILE}: no identity named {unknown[0]!r}")
    signers = {name: _public_hex(key) for name, key in roster.keys.items()}
    _write_roster(directory, signers, [*roster.revoked, *names], _ca_key(directory))
    return load_roster(directory)
