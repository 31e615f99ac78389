"""`ground-cli gui --token-file`: the token read from a file only its owner reads, or a
new one made there; never from a file others can read or through a link."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ground.gui.cli import TokenError, read_token_file


def written(path: Path, text: str, mode: int = 0o600) -> Path:
    """`path` holding `text`, with the permissions `mode`."""
    path.write_text(text)
    path.chmod(mode)
    return path


def test_a_token_file_is_read_and_a_missing_one_is_made_owner_only(tmp_path: Path) -> None:
    assert read_token_file(written(tmp_path / "given", "  abc-123\n")) == "abc-123"
    made = tmp_path / "made"
    token = read_token_file(made)
    assert len(token) >= 24
    assert made.read_text().strip() == token
    assert made.stat().st_mode & 0o777 == 0o600
    assert read_token_file(made) == token  # the same one next time


def test_a_token_file_others_can_read_is_refused_with_the_fix(tmp_path: Path) -> None:
    shared = written(tmp_path / "shared", "abc\n", 0o644)
    with pytest.raises(TokenError, match="chmod 600"):
        read_token_file(shared)


def test_an_empty_token_file_or_a_link_is_refused(tmp_path: Path) -> None:
    empty = written(tmp_path / "empty", "\n")
    with pytest.raises(TokenError, match="one token"):
        read_token_file(empty)
    link = tmp_path / "link"
    os.symlink(written(tmp_path / "target", "abc\n"), link)
    with pytest.raises(TokenError, match="cannot read"):
        read_token_file(link)
