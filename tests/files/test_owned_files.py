"""Certificate files cannot be captured: `fleet certs make` and `revoke` refuse a
directory another user can change, and a file planted where a key will be written."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fleet.errors import CertError
from fleet.files.certs import write_identities
from fleet.files.owned_files import check_directory, check_replaceable, read_own
from fleet.files.signers import RosterError, revoke
from programs.fleet_cli import main as fleet_main

#: Another user (nobody): the attacker, where the test may chown to it (as root).
ATTACKER = 65534
as_root = pytest.mark.skipif(os.geteuid() != 0, reason="needs root to own files as another user")


def make(directory: Path) -> int:
    return fleet_main(["certs", "make", str(directory), "--uavs", "74", "--ground"])


def test_a_hard_link_planted_at_a_signing_key_is_refused_and_gets_no_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    certs = tmp_path / "certs"
    certs.mkdir(mode=0o700)
    loot = tmp_path / "loot"  # a file the attacker can read later
    loot.write_text("")
    os.link(loot, certs / "uav-74.sign")
    assert make(certs) != 0
    assert "uav-74.sign: has 2 links" in capsys.readouterr().err
    assert "PRIVATE KEY" not in loot.read_text()


@as_root
def test_a_planted_file_of_another_user_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    certs = tmp_path / "certs"
    certs.mkdir(mode=0o700)
    loot = tmp_path / "loot"
    loot.write_text("")
    os.chown(loot, ATTACKER, ATTACKER)
    os.link(loot, certs / "ground.sign")
    assert make(certs) != 0
    assert "ground.sign: owned by uid 65534, not by you" in capsys.readouterr().err
    assert loot.read_text() == ""


@pytest.mark.parametrize("mode", [0o777, 0o1777, 0o770])
def test_a_directory_others_can_write_is_refused_before_anything_is_written(
    tmp_path: Path, mode: int, capsys: pytest.CaptureFixture[str]
) -> None:
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(mode)
    if mode == 0o770:
        if os.geteuid() != 0:
            pytest.skip("needs root to give the directory another group")
        os.chown(shared, -1, ATTACKER)
    assert make(shared) != 0
    err = capsys.readouterr().err
    assert f"{shared}: writable by" in err and "chmod go-w" in err
    assert list(shared.iterdir()) == []  # no key written


@as_root
def test_an_attacker_owned_directory_is_refused(tmp_path: Path) -> None:
    theirs = tmp_path / "theirs"
    theirs.mkdir(mode=0o755)
    os.chown(theirs, ATTACKER, ATTACKER)
    with pytest.raises(CertError, match="owned by uid 65534, not by you"):
        write_identities(theirs / "certs", ["ground"], [])
    assert not (theirs / "certs").exists() or list((theirs / "certs").iterdir()) == []


def test_a_directory_above_that_others_can_write_is_refused_unless_sticky(tmp_path: Path) -> None:
    above = tmp_path / "above"
    (above / "certs").mkdir(parents=True, mode=0o700)
    above.chmod(0o777)
    with pytest.raises(CertError, match=f"{above}: writable by every user"):
        check_directory(above / "certs", CertError)
    above.chmod(0o1777)  # as /tmp: others cannot rename what is in it
    check_directory(above / "certs", CertError)


def test_revoking_in_a_directory_others_can_write_is_refused(tmp_path: Path) -> None:
    certs = tmp_path / "certs"
    write_identities(certs, ["router", "ground", "uav-74"], [])
    certs.chmod(0o777)
    with pytest.raises(RosterError, match="writable by every user"):
        revoke(certs, ["uav-74"])
    certs.chmod(0o755)
    assert revoke(certs, ["uav-74"]).revoked == {"uav-74"}


def test_the_ca_key_is_read_without_following_a_link(tmp_path: Path) -> None:
    certs = tmp_path / "certs"
    write_identities(certs, ["router", "ground", "uav-74"], [])
    (certs / "ca.key").rename(tmp_path / "elsewhere.key")
    (certs / "ca.key").symlink_to(tmp_path / "elsewhere.key")
    with pytest.raises(RosterError, match="the CA key is needed"):
        revoke(certs, ["uav-74"])
    with pytest.raises(RosterError):
        read_own(certs / "ca.key", RosterError)


def test_a_file_of_ones_own_with_one_link_or_a_symlink_may_be_replaced(tmp_path: Path) -> None:
    mine = tmp_path / "mine"
    mine.write_text("old")
    check_replaceable(mine, CertError)
    (tmp_path / "link").symlink_to(mine)
    check_replaceable(tmp_path / "link", CertError)
    check_replaceable(tmp_path / "nothing", CertError)
    (tmp_path / "a-dir").mkdir()
    with pytest.raises(CertError, match="not a regular file"):
        check_replaceable(tmp_path / "a-dir", CertError)
