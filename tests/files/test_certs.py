"""`fleet certs make`: the CA, each identity's certificate, key and Zenoh client config."""

from __future__ import annotations

import ipaddress
import json
import stat
from pathlib import Path

import pytest
import zenoh
from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from fleet.files.certs import IdentityFiles, common_name, endpoint_host
from programs.fleet_cli import main as fleet_main


def make(directory: Path, *extra: str) -> int:
    return fleet_main(["certs", "make", str(directory), "--uavs", "74,112", "--ground", *extra])


def sans(path: Path) -> set[str]:
    certificate = x509.load_pem_x509_certificate(path.read_bytes())
    names = certificate.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    return {str(v) for v in names.get_values_for_type(x509.DNSName)} | {
        str(v) for v in names.get_values_for_type(x509.IPAddress)
    }


def test_every_identity_gets_a_certificate_key_and_client_config(tmp_path: Path) -> None:
    assert make(tmp_path, "--connect", "tls/router:7447") == 0
    ca = x509.load_pem_x509_certificate((tmp_path / "ca.pem").read_bytes())
    for name in ("router", "ground", "uav-74", "uav-112"):
        files = IdentityFiles(tmp_path.resolve(), name)
        files.check()
        assert common_name(files.certificate) == name
        certificate = x509.load_pem_x509_certificate(files.certificate.read_bytes())
        certificate.verify_directly_issued_by(ca)
        assert stat.S_IMODE(files.key.stat().st_mode) == 0o600
        config = json.loads(files.client_config.read_text())
        assert config["connect"]["endpoints"] == ["tls/router:7447"]
        tls = config["transport"]["link"]["tls"]
        assert tls["connect_certificate"] == str(files.certificate)
        assert tls["enable_mtls"] is True
        assert tls["verify_name_on_connect"] is True
        assert tls["close_link_on_expiration"] is True
        assert config["transport"]["shared_memory"] == {"enabled": False}
        zenoh.Config.from_file(str(files.client_config))  # Zenoh itself accepts it


def test_the_ca_names_itself_and_no_identity_is_a_ca(tmp_path: Path) -> None:
    assert make(tmp_path) == 0
    ca = x509.load_pem_x509_certificate((tmp_path / "ca.pem").read_bytes())
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    uav = x509.load_pem_x509_certificate((tmp_path / "uav-74.pem").read_bytes())
    assert not uav.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    assert uav.subject.get_attributes_for_oid(NameOID.COMMON_NAME)[0].value == "uav-74"


def test_configs_can_name_the_directory_where_it_is_mounted(tmp_path: Path) -> None:
    assert make(tmp_path, "--seen-as", "/certs") == 0
    tls = json.loads((tmp_path / "ground.json5").read_text())["transport"]["link"]["tls"]
    assert tls["root_ca_certificate"] == "/certs/ca.pem"
    assert tls["connect_private_key"] == "/certs/ground.key"


def test_a_plain_tcp_endpoint_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert make(tmp_path, "--connect", "tcp/127.0.0.1:7447") == 2
    assert "not a tls/ endpoint" in capsys.readouterr().err


def test_a_bad_uav_list_is_a_usage_error(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="2"):
        fleet_main(["certs", "make", str(tmp_path), "--uavs", "74,x"])


@pytest.mark.parametrize(
    ("endpoint", "host"),
    [
        ("tls/127.0.0.1:7447", "127.0.0.1"),
        ("tls/router:7447", "router"),
        ("tls/[::1]:7447", "::1"),
        ("tls/localhost:7447#iface=lo", "localhost"),
    ],
)
def test_endpoint_host(endpoint: str, host: str) -> None:
    assert endpoint_host(endpoint) == host
    if host[0].isdigit() or ":" in host:
        ipaddress.ip_address(host)


def usages(path: Path) -> set[x509.ObjectIdentifier]:
    certificate = x509.load_pem_x509_certificate(path.read_bytes())
    return set(certificate.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value)


def test_only_routers_may_serve_and_only_they_name_hosts(tmp_path: Path) -> None:
    assert make(tmp_path, "--connect", "tls/router:7447") == 0
    for name in ("router", "router-74", "router-112"):
        assert usages(tmp_path / f"{name}.pem") == {
            ExtendedKeyUsageOID.SERVER_AUTH,
            ExtendedKeyUsageOID.CLIENT_AUTH,
        }
        assert {"127.0.0.1", "localhost", "router"} <= sans(tmp_path / f"{name}.pem")
    for name in ("ground", "uav-74", "uav-112"):
        assert usages(tmp_path / f"{name}.pem") == {ExtendedKeyUsageOID.CLIENT_AUTH}
        with pytest.raises(x509.ExtensionNotFound):
            sans(tmp_path / f"{name}.pem")


def test_an_existing_ca_is_replaced_only_with_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert make(tmp_path) == 0
    before = (tmp_path / "ca.pem").read_bytes()
    assert make(tmp_path) == 1
    assert "a CA is already there" in capsys.readouterr().err
    assert (tmp_path / "ca.pem").read_bytes() == before
    assert make(tmp_path, "--force") == 0
    assert (tmp_path / "ca.pem").read_bytes() != before


def test_a_pre_made_readable_key_file_becomes_owner_only(tmp_path: Path) -> None:
    (tmp_path / "uav-74.key").write_text("old")
    (tmp_path / "uav-74.key").chmod(0o644)
    assert make(tmp_path) == 0
    assert stat.S_IMODE((tmp_path / "uav-74.key").stat().st_mode) == 0o600
    assert "PRIVATE KEY" in (tmp_path / "uav-74.key").read_text()


def test_a_planted_symlink_is_replaced_not_followed(tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.write_text("not a key")
    certs = tmp_path / "certs"
    certs.mkdir()
    (certs / "ground.key").symlink_to(outside)
    assert make(certs) == 0
    assert outside.read_text() == "not a key"  # the key did not go through the link
    assert not (certs / "ground.key").is_symlink()
    assert stat.S_IMODE((certs / "ground.key").stat().st_mode) == 0o600
