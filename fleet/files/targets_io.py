"""Reading and atomically writing `targets.bin` files (the codec is
`fleet.mission.targets_file`).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterable

from fleet.mission.messages import Target
from fleet.mission.targets_file import decode_targets, encode_targets

__all__ = ["read_targets", "write_targets"]

# Mode of a newly created file: mkstemp makes 0600, but targets.bin is an ordinary
# shared data file.
_NEW_FILE_MODE = 0o644


def read_targets(path: str | os.PathLike[str]) -> list[Target]:
    """Read and validate a targets file."""
    with open(path, "rb") as f:
        data = f.read()
    return decode_targets(data, os.fspath(path))


def write_targets(path: str | os.PathLike[str], targets: Iterable[Target]) -> None:
    """Validate, then atomically replace `path` with these targets.

    Written to a temporary file in the same directory (so `os.replace` is a rename
    within one filesystem, atomic on POSIX and Windows), fsynced before the rename so a
    crash cannot leave the new name pointing at unwritten blocks, and the directory is
    fsynced after it so the rename itself survives a crash. On any failure the old file,
    if any, is untouched and the temporary file is removed.
    """
    name = os.fspath(path)
    data = encode_targets(targets, source=name)
    directory = os.path.dirname(os.path.abspath(name))
    try:
        mode = stat.S_IMODE(os.stat(name).st_mode)
    except FileNotFoundError:
        mode = _NEW_FILE_MODE
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{os.path.basename(name)}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            # Before the fsync, so the mode is as durable as the data.
            os.chmod(tmp, mode)
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, name)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    _fsync_directory(directory)


def _fsync_directory(directory: str) -> None:
    # Directories cannot be opened for fsync on Windows; there the rename is already
    # as durable as the platform offers.
    if os.name != "posix":
        return
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
