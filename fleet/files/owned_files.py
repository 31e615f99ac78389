"""Where the fleet's private keys are written: only into a directory no one else can
change, and never into a file someone else planted.

A private key written into a directory another user can write can be taken: the other
user swaps `ca.pem` or `signers.json` for their own, or plants a hard link at the
name the key will be written to (a hard link is no symlink: O_NOFOLLOW does not see
it), and the key lands in a file the other user owns. So, before writing:

* the directory and each directory above it must be owned by this user (or root), and
  writable by no one else: not by every user (unless sticky, as /tmp, whose entries only
  their owner may rename), not by a group other than this user's own;
* a file already at a name to write must be this user's, with one link only; it is then
  removed and the new one created exclusively (O_EXCL), never through a link
  (O_NOFOLLOW).

What a check refuses raises `error` (the caller's own error type) naming the path and
what is wrong; nothing is written then.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from fleet.errors import FleetError


def _whose(info: os.stat_result) -> str:
    return f"uid {info.st_uid}"


def _others_can_write(info: os.stat_result, sticky_ok: bool) -> str | None:
    """Who else may change entries of a directory with `info`; None: no one. A sticky
    directory (/tmp) lets others add entries but not rename or remove this user's."""
    if sticky_ok and info.st_mode & stat.S_ISVTX:
        return None
    if info.st_mode & stat.S_IWOTH:
        return "every user"
    if info.st_mode & stat.S_IWGRP and info.st_gid != os.getegid():
        return f"group {info.st_gid}"
    return None


def check_directory(directory: Path, error: type[FleetError]) -> None:
    """Raise `error` unless `directory` (absolute) and every directory above it are
    this user's or root's and writable by no one else (above it: or sticky)."""
    me = os.geteuid()
    for place in (directory, *directory.parents):
        try:
            info = os.stat(place)
        except OSError as failure:
            raise error(f"{place}: {failure.strerror or failure}") from None
        if not stat.S_ISDIR(info.st_mode):
            raise error(f"{place}: not a directory")
        if info.st_uid not in (me, 0):
            raise error(
                f"{place}: owned by {_whose(info)}, not by you: another user could swap the "
                "files in it (choose a directory of your own)"
            )
        who = _others_can_write(info, sticky_ok=place != directory)
        if who is not None:
            raise error(
                f"{place}: writable by {who}: they could swap the files in it "
                f"(chmod go-w {place}, or choose another directory)"
            )


def check_replaceable(path: Path, error: type[FleetError]) -> None:
    """Raise `error` unless nothing is at `path`, or a file (or symlink) of this user's
    with one link: what may be removed and written afresh."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as failure:
        raise error(f"{path}: {failure.strerror or failure}") from None
    if info.st_uid != os.geteuid():
        raise error(f"{path}: owned by {_whose(info)}, not by you: not overwritten")
    if stat.S_ISLNK(info.st_mode):
        return  # removed, never followed
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: not a regular file: not overwritten")
    if info.st_nlink > 1:
        raise error(
            f"{path}: has {info.st_nlink} links (a hard link elsewhere would receive what is "
            "written here): not overwritten; remove it and every other link"
        )


def write_new(path: Path, data: bytes, error: type[FleetError], private: bool = False) -> None:
    """Write `path` afresh (after `check_replaceable`): the old entry removed, the new
    file created exclusively, never through a link; owner-only when `private`."""
    check_replaceable(path, error)
    try:
        path.unlink(missing_ok=True)
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
        descriptor = os.open(path, flags, 0o600 if private else 0o644)
        with os.fdopen(descriptor, "wb") as f:
            f.write(data)
    except OSError as failure:
        raise error(f"cannot write {path}: {failure.strerror or failure}") from None


def read_own(path: Path, error: type[FleetError], limit: int = 1 << 20) -> bytes:
    """The bytes of `path`, a file of this user's with one link, opened without
    following a link (a private key about to be used to sign)."""
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as failure:
        raise error(f"{path}: {failure.strerror or failure}") from None
    with os.fdopen(descriptor, "rb") as f:
        info = os.fstat(f.fileno())
        if info.st_uid != os.geteuid() or info.st_nlink != 1 or not stat.S_ISREG(info.st_mode):
            raise error(
                f"{path}: not a file of yours with one link ({_whose(info)}, "
                f"{info.st_nlink} links): not used"
            )
        return f.read(limit)


def read_private(path: Path, error: type[FleetError], limit: int) -> bytes:
    """The first `limit` bytes of `path`, a secret (a token, passphrases): opened without
    following a link, and refused (`error`) if its group or others may read or write it.
    An OSError opening or reading it passes through: the caller says it (or, for a file
    not there yet, makes one)."""
    descriptor = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    with os.fdopen(descriptor, "rb") as f:
        info = os.fstat(f.fileno())
        if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise error(
                f"{path}: readable or writable by others (mode {stat.S_IMODE(info.st_mode):o}); "
                f"chmod 600 {path}"
            )
        return f.read(limit)
