"""The signing keys and the roster on disk: written with the identities, believed only
when the fleet's CA signed them, and revocation."""

from __future__ import annotations

import io
import json
import stat
from pathlib import Path

import pytest

from fleet.files.certs import write_identities
from fleet.files.signers import (
    ROSTER_FILE,
    RosterError,
    load_roster,
    load_signing_key,
    revoke,
    revoked_identities,
    signing_key_path,
)
from fleet.mission.key_space import KeySpace
from fleet.mission.signature import Delivery, sign, verify
from fleet.tools.certs_command import RevokeOptions, run_revoke

NAMES = ["router", "ground", "uav-74", "uav-112"]


@pytest.fixture
def certs(tmp_path: Path) -> Path:
    write_identities(tmp_path, NAMES, [])
    return tmp_path


def test_each_identity_gets_a_private_signing_key_and_the_roster_names_them(certs: Path) -> None:
    roster = load_roster(certs)
    assert set(roster.keys) == set(NAMES) and roster.revoked == frozenset()
    space = KeySpace()
    key = space.mission_result(5, 74)
    for name in NAMES:
        path = signing_key_path(certs, name)
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
    attachment = sign(load_signing_key(signing_key_path(certs, "uav-74")), "uav-74", key, b"{}", 1)
    assert verify(roster, space, key, b"{}", attachment, Delivery.PUT)[1] is None


def test_a_roster_the_ca_did_not_sign_is_not_believed(certs: Path, tmp_path: Path) -> None:
    path = certs / ROSTER_FILE
    document = json.loads(path.read_text())
    # An attacker swaps in their own key for the ground's.
    document["signers"]["ground"] = document["signers"]["uav-74"]
    path.write_text(json.dumps(document))
    with pytest.raises(RosterError, match="not signed by the CA"):
        load_roster(certs)
    # A roster signed by another CA.
    other = tmp_path / "other"
    write_identities(other, NAMES, [])
    (certs / ROSTER_FILE).write_bytes((other / ROSTER_FILE).read_bytes())
    with pytest.raises(RosterError, match="not signed by the CA"):
        load_roster(certs)
    for garbage in (b"", b"[]", b'{"signers": 1}', b"[" * 100_000):
        path.write_bytes(garbage)
        with pytest.raises(RosterError):
            load_roster(certs)


def test_revoking_an_identity_lists_it_and_keeps_the_roster_signed(
    certs: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert revoked_identities(certs) == frozenset()
    roster = revoke(certs, ["uav-74"])
    assert roster.revoked == {"uav-74"} and set(roster.keys) == set(NAMES)
    assert load_roster(certs).revoked == {"uav-74"}
    with pytest.raises(RosterError, match="no identity named 'uav-9'"):
        revoke(certs, ["uav-9"])

    out = io.StringIO()
    assert run_revoke(RevokeOptions(directory=certs, names=["uav-112"]), out) == 0
    assert "revokes uav-112, uav-74" in out.getvalue()
    assert revoked_identities(certs) == {"uav-74", "uav-112"}


def test_revoking_needs_the_ca_key(certs: Path) -> None:
    (certs / "ca.key").unlink()
    with pytest.raises(RosterError, match="the CA key is needed"):
        revoke(certs, ["uav-74"])
