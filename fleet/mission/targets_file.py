"""`targets.bin`: the Mission Manager's saved targets (thesis 3.1.3), bytes <-> targets.

Format, as the thesis's GUI wrote it: for each target, latitude (degrees), longitude
(degrees) and altitude (metres), each an IEEE-754 double, little-endian, no header, so
24 bytes a target and the target count is the file length / 24.

With no header and no checksum, the only defence against a truncated or foreign file is
validation, so reading refuses anything that is not a whole, non-empty sequence of
finite, in-range targets, and every refusal says which file, which target, at which
byte offset, and what was expected. The checks are a pilot's: latitude and longitude on
the globe, altitude inside ALTITUDE_ENVELOPE_M, at most MAX_TARGETS targets (the planner
answers every target within its budget only up to about that many), and a text file (a
CSV, say) is named as such rather than read as numbers. Encoding validates the same
way, so a bad target list is refused before anything is written.

This is the pure codec; reading and atomically writing the file are
`fleet.files.targets_io`'s.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable

from fleet.errors import CodecError
from fleet.mission.messages import MAX_TARGETS, Target

__all__ = [
    "ALTITUDE_ENVELOPE_M",
    "MAX_TARGETS",
    "TARGET_SIZE",
    "TargetsFileError",
    "decode_targets",
    "encode_targets",
]

_RECORD = struct.Struct("<3d")
#: Bytes a target: three little-endian f64.
TARGET_SIZE = _RECORD.size
#: Target altitudes accepted, metres above mean sea level: from below sea level (Death
#: Valley) to the ceiling of a Piccolo-class aircraft.
ALTITUDE_ENVELOPE_M = (-100.0, 6000.0)
#: Bytes of a text file: printable ASCII and the usual white space.
_TEXT_BYTES = frozenset(range(0x20, 0x7F)) | {0x09, 0x0A, 0x0D}


class TargetsFileError(CodecError):
    """A targets file, or a target list about to be written, is malformed.

    The message names the file, the target index, its byte offset and what was expected;
    the same facts are kept as attributes for callers that want them.
    """

    def __init__(self, source: str, index: int, offset: int, problem: str) -> None:
        super().__init__(f"{source}: target {index} at byte offset {offset}: {problem}")
        self.source = source
        self.index = index
        self.offset = offset
        self.problem = problem


def _validate(target: Target, index: int, source: str) -> None:
    offset = index * TARGET_SIZE
    fields = (("latitude", target.lat), ("longitude", target.lon), ("altitude", target.alt))
    for name, value in fields:
        if not math.isfinite(value):
            raise TargetsFileError(
                source, index, offset, f"{name} is {value!r}, expected a finite number"
            )
    if not -90.0 <= target.lat <= 90.0:
        raise TargetsFileError(
            source, index, offset, f"latitude {target.lat!r} is outside [-90, 90] degrees"
        )
    if not -180.0 <= target.lon <= 180.0:
        raise TargetsFileError(
            source, index, offset, f"longitude {target.lon!r} is outside [-180, 180] degrees"
        )
    low, high = ALTITUDE_ENVELOPE_M
    if not low <= target.alt <= high:
        raise TargetsFileError(
            source,
            index,
            offset,
            f"altitude {target.alt!r} m is outside the envelope [{low:g}, {high:g}] m",
        )


def _refuse_too_many(count: int, source: str) -> None:
    raise TargetsFileError(
        source,
        MAX_TARGETS,
        MAX_TARGETS * TARGET_SIZE,
        f"{count} targets: at most {MAX_TARGETS} targets a mission",
    )


def _refuse_text(data: bytes, source: str) -> None:
    """A file of nothing but printable text is a text file, not binary records."""
    if all(byte in _TEXT_BYTES for byte in data[:4096]):
        first = data.split(b"\n", 1)[0][:40].decode("ascii")
        raise TargetsFileError(
            source,
            0,
            0,
            f"this is a text file (it starts {first!r}), expected binary records of three "
            "little-endian f64 (lat, lon, alt); make one with `ground-cli targets make`",
        )


def _refuse_empty(source: str) -> None:
    raise TargetsFileError(
        source, 0, 0, f"no targets: expected at least one target of {TARGET_SIZE} bytes"
    )


def decode_targets(data: bytes, source: str) -> list[Target]:
    """Targets from the bytes of a targets file; `source` names it in errors."""
    if not data:
        _refuse_empty(source)
    _refuse_text(data, source)
    whole, leftover = divmod(len(data), TARGET_SIZE)
    if leftover:
        offset = whole * TARGET_SIZE
        raise TargetsFileError(
            source,
            whole,
            offset,
            f"length {len(data)} is not a multiple of {TARGET_SIZE}: {leftover} leftover "
            f"bytes at offset {offset}, expected {TARGET_SIZE} bytes a target "
            "(truncated or not a targets file?)",
        )
    if whole > MAX_TARGETS:
        _refuse_too_many(whole, source)
    targets = []
    for index, (lat, lon, alt) in enumerate(_RECORD.iter_unpack(data)):
        target = Target(lat=lat, lon=lon, alt=alt)
        _validate(target, index, source)
        targets.append(target)
    return targets


def encode_targets(targets: Iterable[Target], *, source: str = "<targets>") -> bytes:
    """The bytes of a targets file; refuses what `decode_targets` would refuse."""
    chunks = []
    for index, target in enumerate(targets):
        _validate(target, index, source)
        chunks.append(_RECORD.pack(target.lat, target.lon, target.alt))
    if not chunks:
        _refuse_empty(source)
    if len(chunks) > MAX_TARGETS:
        _refuse_too_many(len(chunks), source)
    data = b"".join(chunks)
    # Targets whose every byte is printable (rare: one in about 10^10 single-target
    # files) would be read back as a text file; refuse them here rather than write a
    # file the decoder refuses.
    _refuse_text(data, source)
    return data
