"""The fleet's identities for mutual TLS: a CA, and a certificate and key per identity.

`write_identities` makes `DIR/ca.pem` (and `DIR/ca.key`, kept to issue more later) and,
per identity NAME (`ground`, `router`, `uav-74`, ...), `DIR/NAME.pem` (CN = NAME, SANs for
the hosts the fleet is reached at), `DIR/NAME.key` and `DIR/NAME.json5`: a ready Zenoh
client configuration for that identity (`--zenoh-config`). Keys are ECDSA P-256, which
Zenoh's TLS (rustls) accepts; private keys are written readable by their owner only.

Identities have one role each. Only a router's certificate may serve (TLS server usage,
and the names of the hosts it is reached at); it may also connect, to another router. Every
other identity (the ground, a UAV) may only connect: a client checks that the router it
dialled presents a server certificate for that host, so a stolen UAV key cannot pose as a
router. Private keys are created owner-only with O_EXCL and never through a symlink, only
in a directory no other user can change, never over a file another user owns or one
with a second (hard) link (`owned_files`); an existing CA is replaced only when asked
(`force`).
"""

from __future__ import annotations

import datetime
import ipaddress
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from fleet.errors import CertError as CertError  # raised here, defined where it is light
from fleet.files.owned_files import check_directory, write_new
from fleet.files.signers import write_signers
from fleet.mission.access import is_router_identity

#: Hosts every certificate names, so endpoints on this machine verify.
LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")
DEFAULT_VALID_DAYS = 365
CA_NAME = "ca"


@dataclass(frozen=True)
class Authority:
    certificate: x509.Certificate
    key: ec.EllipticCurvePrivateKey


def endpoint_host(endpoint: str) -> str:
    """`tls/router:7447` -> `router`; `tls/[::1]:7447` -> `::1`."""
    _, _, address = endpoint.partition("/")
    address = address.split("#", 1)[0]
    host = address.rpartition(":")[0] if ":" in address else address
    return host.strip("[]")


def _san(hosts: list[str]) -> x509.SubjectAlternativeName:
    names: list[x509.GeneralName] = []
    for host in dict.fromkeys(hosts):
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return x509.SubjectAlternativeName(names)


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "uav-fleet"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def _validity(lifetime: datetime.timedelta) -> tuple[datetime.datetime, datetime.datetime]:
    now = datetime.datetime.now(datetime.UTC)
    # An hour of slack for clocks that disagree a little.
    return now - datetime.timedelta(hours=1), now + lifetime


def certificate_builder(
    key: ec.EllipticCurvePrivateKey,
    subject: x509.Name,
    issuer: x509.Name,
    lifetime: datetime.timedelta,
) -> x509.CertificateBuilder:
    """A certificate of `key` for `subject` from `issuer` (itself for a self-signed one),
    valid from an hour ago for `lifetime`, with a random serial: the caller adds its
    extensions and signs it."""
    start, end = _validity(lifetime)
    return (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
    )


def _days(days: int) -> datetime.timedelta:
    return datetime.timedelta(days=days)


DEFAULT_LIFETIME = _days(DEFAULT_VALID_DAYS)


def make_authority(days: int = DEFAULT_VALID_DAYS) -> Authority:
    key = ec.generate_private_key(ec.SECP256R1())
    name = _name("uav-fleet CA")
    certificate = (
        certificate_builder(key, name, name, _days(days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return Authority(certificate, key)


def issue(
    authority: Authority,
    common_name: str,
    hosts: list[str],
    lifetime: datetime.timedelta = DEFAULT_LIFETIME,
) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    """A certificate for `common_name` signed by `authority`, valid for `lifetime`.

    A router's (`is_router_identity`) may serve, for `hosts`, and connect; any other
    identity's may only connect, and names no host.
    """
    key = ec.generate_private_key(ec.SECP256R1())
    ca_key_id = x509.AuthorityKeyIdentifier.from_issuer_public_key(authority.key.public_key())
    router = is_router_identity(common_name)
    usages = [ExtendedKeyUsageOID.SERVER_AUTH] if router else []
    builder = (
        certificate_builder(key, _name(common_name), authority.certificate.subject, lifetime)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage([*usages, ExtendedKeyUsageOID.CLIENT_AUTH]), critical=True
        )
        .add_extension(ca_key_id, critical=False)
    )
    if router:
        builder = builder.add_extension(_san(hosts), critical=False)
    return builder.sign(authority.key, hashes.SHA256()), key


# ---- files ----------------------------------------------------------------------------------
def _pem(certificate: x509.Certificate) -> bytes:
    return certificate.public_bytes(serialization.Encoding.PEM)


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _write(path: Path, data: bytes, private: bool = False) -> None:
    """Write `path` afresh: an old file of this user's with one link (or a symlink) is
    removed first, anything else refused, and the new one created exclusively without
    following a link, so a pre-made file's mode, a planted symlink or hard link cannot
    carry a private key elsewhere or leave it readable (`owned_files`)."""
    write_new(path, data, CertError, private)


@dataclass(frozen=True)
class IdentityFiles:
    """Where one identity's files are (absolute paths)."""

    directory: Path
    name: str

    @property
    def ca(self) -> Path:
        return self.directory / f"{CA_NAME}.pem"

    @property
    def certificate(self) -> Path:
        return self.directory / f"{self.name}.pem"

    @property
    def key(self) -> Path:
        return self.directory / f"{self.name}.key"

    @property
    def client_config(self) -> Path:
        return self.directory / f"{self.name}.json5"

    def check(self) -> None:
        """Raise CertError naming the first of this identity's files that is missing."""
        for path in (self.ca, self.certificate, self.key):
            if not path.is_file():
                raise CertError(
                    f"{path}: missing (make the fleet's identities with `fleet certs make`)"
                )


def tls_settings(files: IdentityFiles) -> dict[str, Any]:
    """`transport/link/tls` for `files`' identity: mutual TLS, listening and connecting,
    the dialled router's name checked, and every link closed when the certificate at its
    other end expires."""
    return {
        "root_ca_certificate": str(files.ca),
        "listen_certificate": str(files.certificate),
        "listen_private_key": str(files.key),
        "connect_certificate": str(files.certificate),
        "connect_private_key": str(files.key),
        "enable_mtls": True,
        "verify_name_on_connect": True,
        "close_link_on_expiration": True,
    }


def client_config(files: IdentityFiles, connect: list[str]) -> dict[str, Any]:
    """A whole Zenoh client configuration for `files`' identity, connecting to `connect`."""
    return {
        "mode": "client",
        "connect": {"endpoints": list(connect)},
        "scouting": {"multicast": {"enabled": False}, "delay": 0},
        # As the built-in config (fleet.transport.zenoh_config): no shared memory.
        "transport": {"link": {"tls": tls_settings(files)}, "shared_memory": {"enabled": False}},
    }


def write_identities(
    directory: Path,
    names: list[str],
    connect: list[str],
    days: int = DEFAULT_VALID_DAYS,
    seen_as: Path | None = None,
    force: bool = False,
    lifetime: dict[str, datetime.timedelta] | None = None,
) -> list[IdentityFiles]:
    """A new CA and, for each of `names`, its certificate, key and client config.

    The client configs name the files under `seen_as` when given (where `directory` is
    mounted on the machines that use them, e.g. `/certs` in a container). An existing CA
    in `directory` is a CertError unless `force`: replacing it orphans every identity it
    issued. `lifetime` gives some identities another validity than `days` (tests of
    expiry).
    """
    directory = directory.resolve()
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CertError(f"cannot create {directory}: {error.strerror or error}") from None
    check_directory(directory, CertError)
    ca_files = [directory / f"{CA_NAME}.{suffix}" for suffix in ("pem", "key")]
    existing = [path for path in ca_files if path.is_symlink() or path.exists()]
    if existing and not force:
        raise CertError(
            f"{existing[0]}: a CA is already there; replacing it invalidates every identity "
            "it issued (use --force to make a new one)"
        )
    authority = make_authority(days)
    _write(ca_files[0], _pem(authority.certificate))
    _write(ca_files[1], _key_pem(authority.key), private=True)
    hosts = [*LOCAL_HOSTS, *(endpoint_host(e) for e in connect)]
    written = []
    for name in names:
        files = IdentityFiles(directory, name)
        validity = (lifetime or {}).get(name, _days(days))
        certificate, key = issue(authority, name, hosts, validity)
        _write(files.certificate, _pem(certificate))
        _write(files.key, _key_pem(key), private=True)
        named = IdentityFiles(seen_as, name) if seen_as is not None else files
        config = json.dumps(client_config(named, connect), indent=2) + "\n"
        _write(files.client_config, config.encode())
        written.append(files)
    write_signers(directory, names, authority.key)  # the signed-commands roster
    return written


def common_name(path: Path) -> str:
    """The CN of the certificate in `path`; raises CertError if it cannot be read."""
    try:
        certificate = x509.load_pem_x509_certificate(path.read_bytes())
    except (OSError, ValueError) as error:
        raise CertError(f"{path}: not a readable PEM certificate: {error}") from None
    names = certificate.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(names[0].value) if names else ""
