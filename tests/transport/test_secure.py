"""The secure profile's set-up errors: each names what is missing or wrong."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import zenoh

from fleet.files.certs import CertError, write_identities
from fleet.files.signers import revoke
from fleet.launch.launcher import Fleet, FleetSpec, LaunchError
from fleet.transport.router import main as router_main
from fleet.transport.secure import SecureProfile


def test_the_profile_is_the_uavs_with_an_identity(tmp_path: Path) -> None:
    write_identities(tmp_path, ["router", "ground", "uav-74", "uav-112"], [])
    profile = SecureProfile.load(tmp_path)
    assert profile.uav_ids == (74, 112)
    assert profile.uav_config(74) == tmp_path.resolve() / "uav-74.json5"
    with pytest.raises(CertError, match=r"uav-5\.pem: missing"):
        profile.uav_config(5)


def test_no_directory_or_no_router_identity_is_refused(tmp_path: Path) -> None:
    with pytest.raises(CertError, match="no such directory"):
        SecureProfile.load(tmp_path / "nowhere")
    write_identities(tmp_path, ["ground"], [])
    with pytest.raises(CertError, match=r"router\.pem: missing"):
        SecureProfile.load(tmp_path)


def test_the_router_command_says_what_is_missing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert router_main(["--secure", str(tmp_path / "nowhere")]) == 2
    assert "no such directory" in capsys.readouterr().err


def test_fleet_up_secure_needs_a_tls_endpoint(tmp_path: Path) -> None:
    write_identities(tmp_path, ["router", "ground", "uav-112"], [])
    spec = FleetSpec(
        "single_uav", listen="tcp/127.0.0.1:7447", secure_dir=tmp_path, log_dir=tmp_path / "logs"
    )
    with (
        pytest.raises(LaunchError, match=r"tls/ endpoints, not tcp/127\.0\.0\.1:7447"),
        Fleet(spec),
    ):
        pass


def test_a_config_with_mutual_tls_is_the_secure_profiles(tmp_path: Path) -> None:
    from fleet.transport.zenoh_config import build_config, make_config, uses_mtls

    write_identities(tmp_path, ["router", "uav-74"], [])
    assert uses_mtls(build_config(config_file=str(tmp_path / "uav-74.json5")))
    assert not uses_mtls(make_config("client", ["tcp/127.0.0.1:7447"]))


def test_a_revoked_identity_is_granted_nothing(tmp_path: Path) -> None:
    write_identities(tmp_path, ["router", "ground", "uav-74", "uav-112"], [])
    revoke(tmp_path, ["uav-74", "ground"])
    profile = SecureProfile.load(tmp_path)
    assert profile.uav_ids == (112,)
    config = zenoh.Config()
    profile.apply_to_router(config)
    acl = json.loads(config.get_json("access_control"))
    named = {name for subject in acl["subjects"] for name in subject["cert_common_names"]}
    assert named == {"router-112", "uav-112"}  # UAV 112 and its own router
