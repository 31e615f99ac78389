"""MAVLink 2 message signing for the gateway: a secret per ground station.

A signed MAVLink 2 frame carries a link id, a 48-bit timestamp (10 µs since 2015-01-01)
and the first 6 bytes of SHA-256(secret + the frame up to the signature). With
`fleet mavlink --signing-key FILE`, every frame a station sends must be signed with
one of the secrets in FILE, with a timestamp newer than the last of its stream (link
id, system, component) and, for a new stream, not more than a minute older than the
newest the gateway knows (the MAVLink rule): what is not is dropped and counted
(`unsigned`, `bad_signature`, `replayed`). A station is bound to the secret it signed
its first accepted frame with; what the gateway sends it is signed with that secret.

FILE holds one station a line, `NAME PASSPHRASE`; the secret is SHA-256 of the
passphrase, as MAVProxy (`signing key PASSPHRASE`) and QGroundControl derive it. It
must be readable by its owner only. Lines starting with `#` are comments.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

from fleet.errors import FleetError

#: The signing timestamp's epoch (2015-01-01 UTC) and unit (10 µs).
EPOCH_2015 = 1420070400
TICKS_PER_S = 100_000
#: How far behind the newest timestamp known a new stream may start (one minute).
NEW_STREAM_SLACK = 60 * TICKS_PER_S
#: Streams remembered at most (the oldest forgotten first).
MAX_STREAMS = 4096
_SIGNATURE = 13  # link id (1), timestamp (6), signature (6)
MAX_KEY_FILE = 65_536


class SigningKeyError(FleetError, ValueError):
    """A signing-key file that cannot be used; the message names the file and line."""


@dataclass(frozen=True)
class StationKey:
    name: str
    secret: bytes  #: 32 bytes


def passphrase_secret(passphrase: str) -> bytes:
    """The 32-byte secret MAVProxy and QGroundControl derive from a passphrase."""
    return hashlib.sha256(passphrase.encode()).digest()


def load_keys(path: Path) -> tuple[StationKey, ...]:
    """The stations' secrets in `path` (`NAME PASSPHRASE` a line)."""
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as error:
        raise SigningKeyError(f"{path}: {error.strerror or error}") from None
    with os.fdopen(descriptor, "rb") as f:
        info = os.fstat(f.fileno())
        if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise SigningKeyError(
                f"{path}: readable or writable by others (mode {stat.S_IMODE(info.st_mode):o}); "
                f"chmod 600 {path}"
            )
        text = f.read(MAX_KEY_FILE).decode("utf-8", "replace")
    keys: dict[str, StationKey] = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, _, passphrase = line.partition(" ")
        passphrase = passphrase.strip()
        if not passphrase:
            raise SigningKeyError(f"{path}, line {number}: expected NAME PASSPHRASE")
        if name in keys:
            raise SigningKeyError(f"{path}, line {number}: station {name!r} given twice")
        keys[name] = StationKey(name, passphrase_secret(passphrase))
    if not keys:
        raise SigningKeyError(f"{path}: no station (one `NAME PASSPHRASE` a line)")
    return tuple(keys.values())


def timestamp_now(wall: Callable[[], float] = time.time) -> int:
    return max(0, int((wall() - EPOCH_2015) * TICKS_PER_S))


class Verdict(StrEnum):
    """What a frame's signature says (the values are the drop reasons)."""

    OK = "ok"
    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad_signature"
    REPLAYED = "replayed"


def _signed(message: mavlink2.MAVLink_message) -> bytes | None:
    """The frame as it came, if it carries a signature."""
    header = message.get_header()
    if header is None or not header.incompat_flags & mavlink2.MAVLINK_IFLAG_SIGNED:
        return None
    frame = bytes(message.get_msgbuf())
    return frame if len(frame) > _SIGNATURE else None


class Verifier:
    """Checks each frame against the stations' secrets and its stream's timestamps."""

    def __init__(self, keys: tuple[StationKey, ...], wall: Callable[[], float] = time.time):
        self.keys = keys
        self._wall = wall
        self._streams: OrderedDict[tuple[str, int, int, int], int] = OrderedDict()
        self._newest = 0

    def check(
        self, message: mavlink2.MAVLink_message, bound: StationKey | None
    ) -> tuple[Verdict, StationKey | None]:
        """The verdict on `message`, and the secret it was signed with. A station bound
        to a secret (`bound`) must sign with that one."""
        frame = _signed(message)
        if frame is None:
            return Verdict.UNSIGNED, None
        body, signature = frame[:-6], frame[-6:]
        key = next(
            (
                k
                for k in ((bound,) if bound is not None else self.keys)
                if hmac.compare_digest(hashlib.sha256(k.secret + body).digest()[:6], signature)
            ),
            None,
        )
        if key is None:
            return Verdict.BAD_SIGNATURE, None
        link_id = frame[-_SIGNATURE]
        timestamp = int.from_bytes(frame[-12:-6], "little")
        stream = (key.name, link_id, message.get_srcSystem(), message.get_srcComponent())
        last = self._streams.get(stream)
        newest = max(self._newest, timestamp_now(self._wall))
        if last is not None and timestamp <= last:
            return Verdict.REPLAYED, key
        if last is None and timestamp + NEW_STREAM_SLACK < newest:
            return Verdict.REPLAYED, key
        self._streams[stream] = timestamp
        self._streams.move_to_end(stream)
        if len(self._streams) > MAX_STREAMS:
            self._streams.popitem(last=False)
        self._newest = max(self._newest, timestamp)
        return Verdict.OK, key


def signing_encoder(
    sysid: int, key: StationKey | None, wall: Callable[[], float] = time.time
) -> mavlink2.MAVLink:
    """A pymavlink encoder for system `sysid`, component 1, signing with `key` if given."""
    encoder = mavlink2.MAVLink(None, sysid, 1)
    if key is not None:
        encoder.signing.secret_key = key.secret
        encoder.signing.sign_outgoing = True
        encoder.signing.link_id = 0
        encoder.signing.timestamp = timestamp_now(wall)
    return encoder


def pack(
    encoder: mavlink2.MAVLink, message: mavlink2.MAVLink_message, wall: Callable[[], float]
) -> bytes:
    """`message` packed by `encoder`; its signing timestamp kept no older than the clock
    (a station rejects a stream that falls a minute behind)."""
    if encoder.signing.sign_outgoing:
        encoder.signing.timestamp = max(encoder.signing.timestamp, timestamp_now(wall))
    data = bytes(message.pack(encoder))
    encoder.seq = (encoder.seq + 1) % 256
    return data
