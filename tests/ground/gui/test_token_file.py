"""`ground-cli gui --token-file`: the token read from a file only its owner reads, or a
new one made there; never from a file others can read or through a link."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ground.gui.cli import TokenError, read_token_file


def test_a_token_file_is_read_and_a_missing_one_is_made_owner_only(tmp_path: Path) -> None:
    given = tmp_path / "given"
    given.write_text("  abc-123\n")
    given.chmod(0o600)
    assert read_token_file(given) == "abc-123"
    made = tmp_path / "made"
    token = read_token_file(made)
    assert len(token) >= 24
    assert made.read_text().strip() == token
    assert made.stat().st_mode & 0o777 == 0o600
    assert read_token_file(made) == token  # the same one next time


def test_a_token_file_others_can_read_is_refused_with_the_fix(tmp_path: Path) -> None:
    shared = tmp_path / "shared"
    shared.write_text("abc\n")
    shared.chmod(0o644)
    with pytest.raises(TokenError, match="chmod 600"):
        read_token_file(shared)


def test_an_empty_token_file_or_a_link_is_refused(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.write_text("\n")
    empty.chmod(0o600)
    with pytest.raises(TokenError, match="one token"):
        read_token_file(empty)
    target = tmp_path / "target"
    target.write_text("abc\n")
    target.chmod(0o600)
    link = tmp_path / "link"
    os.symlink(target, link)
    with pytest.raises(TokenError, match="cannot read"):
        read_token_file(link)
