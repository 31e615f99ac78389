"""Signed commands and decisions: the envelope, who may sign which key, and freshness.

Trust on the bus is per hop (mutual TLS, the router's ACL); a message that is relayed
(a router, a teammate answering a catch-up query) would be believed for whoever handed
it over. A signed message is believed for its *author*: the envelope carries the
author's identity (a certificate's common name: `ground`, `uav-74`), a timestamp and an
Ed25519 signature over the key expression, the payload, the author and the timestamp.
It travels in the Zenoh attachment, so the message structs (and the open profile, which
signs nothing) stay as they are.

Which keys are signed, and by whom, follows the key registry, the single source the
router's access policy (`fleet.mission.access`) is derived from too: a key that
commands the fleet or carries the team's decisions (`Role.COMMAND`, the whole mission
tree, a UAV's state) must be signed by its registered writer (the ground for missions,
aborts, OPM and autopilot commands; UAV n for its own result, assignment, re-plan,
outcome and state), whoever relays it. A reply on a query-only command key (the
autopilot's `CommandResult`) is signed by the UAV that serves it.

Freshness (`Freshness`): a live message (a put, a command query) must carry a timestamp
within `window` of the receiver's clock and newer than the last one accepted from that
author on that key; a reply to a query (a caught-up message, legitimately old) must
not come from the future, and a mission's abort must not predate the mission's targets
by more than the window (a mission id reused after a fleet restart cannot be aborted by
an old abort). A UAV's state is the exception among replies: it says how the UAV is
*now* (signed as it answers, or relayed by a teammate that heard it put within the
last second), so a state reply signed longer than the window ago is a replay, refused.
"""

from __future__ import annotations

import struct
from collections import OrderedDict
from dataclasses import dataclass
from enum import StrEnum

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from fleet.mission.access import GROUND, is_router_identity, uav_identity
from fleet.mission.delivery import Delivery as Delivery  # its own light module
from fleet.mission.key_registry import (
    DIGEST,
    REGISTRY,
    ROUTER_STATE,
    STATE,
    TARGETS,
    Carriage,
    KeySpec,
    Party,
    Role,
)
from fleet.mission.key_space import KeySpace, space_of

#: The attachment starts with this: a signature envelope, version 1.
MAGIC = b"fsig1"
SIGNATURE_BYTES = 64
#: What every signed byte string starts with: no signature made for another purpose
#: (another protocol using the same key) verifies as one of these.
_DOMAIN = b"uav-fleet signed message v1\x00"
_STAMP = struct.Struct(">Q")
MAX_AUTHOR_BYTES = 64
#: How far (ns) a live message's timestamp may be from the receiver's clock.
DEFAULT_WINDOW_NS = 30 * 1_000_000_000
#: The (author, key) high-water marks kept; older entries past the window are pruned.
MAX_MARKS = 4096
#: The author `author_of` names for a key any router answers for itself (its state):
#: the envelope must be a router identity's, and the reply is that router's word only.
ANY_ROUTER = "router*"


class Refusal(StrEnum):
    """Why a message was refused; each is counted (`bus_codec.DROPPED`) by this name."""

    UNSIGNED = "unsigned"  #: no envelope on a key that needs one
    MALFORMED = "bad_envelope"  #: an attachment that is not an envelope
    UNKNOWN_AUTHOR = "unknown_author"  #: not in the fleet's roster of signers
    REVOKED = "revoked"  #: the author's identity was withdrawn
    NOT_ENTITLED = "not_entitled"  #: the author may not write that key
    BAD_SIGNATURE = "bad_signature"  #: the signature does not match key, payload, author, time
    STALE = "stale"  #: a live message outside the window, or from the future
    REPLAYED = "replayed"  #: not newer than the last accepted on that key, or older than
    #: its mission
    UNVERIFIED = "unverified"  #: a stream sample no signed digest of its author listed


@dataclass(frozen=True)
class Envelope:
    author: str
    stamp_ns: int
    signature: bytes

    def encode(self) -> bytes:
        author = self.author.encode()
        return MAGIC + bytes([len(author)]) + author + _STAMP.pack(self.stamp_ns) + self.signature

    @classmethod
    def decode(cls, data: bytes) -> Envelope | None:
        """The envelope in `data`, or None if it is not one (any bytes at all: never raises)."""
        if not data.startswith(MAGIC) or len(data) < len(MAGIC) + 1:
            return None
        size = data[len(MAGIC)]
        start = len(MAGIC) + 1
        if size == 0 or size > MAX_AUTHOR_BYTES:
            return None
        if len(data) != start + size + _STAMP.size + SIGNATURE_BYTES:
            return None
        try:
            author = data[start : start + size].decode()
        except UnicodeDecodeError:
            return None
        (stamp,) = _STAMP.unpack_from(data, start + size)
        return cls(author, stamp, data[start + size + _STAMP.size :])


def signed_bytes(key: str, payload: bytes, author: str, stamp_ns: int) -> bytes:
    """What is signed: every field length-prefixed, so no two messages share a string."""
    fields = (key.encode(), author.encode(), payload)
    return _DOMAIN + b"".join(struct.pack(">I", len(f)) + f for f in fields) + _STAMP.pack(stamp_ns)


def sign(key_pair: Ed25519PrivateKey, author: str, key: str, payload: bytes, now_ns: int) -> bytes:
    """The attachment that makes `payload` on `key` a message signed by `author`."""
    signature = key_pair.sign(signed_bytes(key, payload, author, now_ns))
    return Envelope(author, now_ns, signature).encode()


def _needs_signature(spec: KeySpec) -> bool:
    return (
        spec.role is Role.COMMAND or spec.tree == "mission" or spec in (STATE, ROUTER_STATE, DIGEST)
    )


#: The keys whose messages must be signed (every other key travels as before).
SIGNED_KEYS: tuple[KeySpec, ...] = tuple(s for s in REGISTRY if _needs_signature(s))
#: A UAV's streams (telemetry, track, waypoint echoes, status, link health): too many
#: samples to sign each, so each is believed once its UAV's signed digest lists it
#: (`fleet.transport.stream_auth`).
STREAM_KEYS: tuple[KeySpec, ...] = tuple(
    s
    for s in REGISTRY
    if s not in SIGNED_KEYS
    and s.writer is Party.OWN_UAV
    and s.carriage is Carriage.PUT
    and s.tree == "uav"
)


def stream_uav(space: KeySpace, key: str) -> int | None:
    """The UAV whose signed digest must vouch for a sample on `key` (None: not a stream)."""
    parsed = space.parse(key)
    if parsed is None or parsed.spec not in STREAM_KEYS or parsed.uav is None:
        return None
    return int(parsed.uav) if parsed.uav.isdecimal() else None


def _party(party: Party, uav: str | None) -> str | None:
    if party is Party.GROUND:
        return GROUND
    if party is Party.OWN_UAV and uav is not None and uav.isdecimal():
        return uav_identity(int(uav))
    return None  # ANY_UAV writes nothing on its own name


def author_of(space: KeySpace, key: str, delivery: Delivery) -> str | None:
    """Who must have signed a message on `key` that arrived as `delivery`; None if the key
    carries no signed message that way (then it is not checked).

    A publication, a command query and a relayed reply carry the registered writer's
    message; a reply on a query-only key is its server's own answer.
    """
    parsed = space.parse(key)
    if parsed is None or parsed.spec not in SIGNED_KEYS:
        return None
    spec = parsed.spec
    query_only = Carriage.PUT not in spec.carriage
    if delivery is Delivery.QUERY:
        # A query's payload is a command only on a query-only key (the autopilot's).
        return _party(spec.writer, parsed.uav) if query_only else None
    if delivery is Delivery.REPLY and query_only:
        if Party.ROUTER in spec.servers:
            return ANY_ROUTER
        servers = [p for p in spec.servers if p is Party.OWN_UAV]
        return _party(servers[0], parsed.uav) if servers else None
    return _party(spec.writer, parsed.uav)


@dataclass(frozen=True)
class Roster:
    """The fleet's signers: each identity's public key, and the identities withdrawn."""

    keys: dict[str, Ed25519PublicKey]
    revoked: frozenset[str] = frozenset()


def verify(
    roster: Roster, space: KeySpace, key: str, payload: bytes, attachment: bytes, how: Delivery
) -> tuple[Envelope | None, Refusal | None]:
    """Check the signature of a message (not its freshness: `Freshness`).

    Returns (envelope, None) for a message signed by the author the key needs, (None,
    None) for a key that needs no signature, else (envelope or None, why refused).
    """
    author = author_of(space, key, how)
    if author is None:
        return None, None
    if not attachment:
        return None, Refusal.UNSIGNED
    envelope = Envelope.decode(attachment)
    if envelope is None:
        return None, Refusal.MALFORMED
    if envelope.author in roster.revoked:
        return envelope, Refusal.REVOKED
    public = roster.keys.get(envelope.author)
    if public is None:
        return envelope, Refusal.UNKNOWN_AUTHOR
    entitled = (
        is_router_identity(envelope.author) if author == ANY_ROUTER else envelope.author == author
    )
    if not entitled:
        return envelope, Refusal.NOT_ENTITLED
    try:
        public.verify(
            envelope.signature, signed_bytes(key, payload, envelope.author, envelope.stamp_ns)
        )
    except InvalidSignature:
        return envelope, Refusal.BAD_SIGNATURE
    return envelope, None


class Freshness:
    """Replay refusal with bounded memory: the last timestamp accepted per (author, key)
    for live messages, and the timestamp of each mission's targets (a bounded number of
    missions) against which that mission's other commands are judged.

    The marks live in memory, so a restarted process would believe a command replayed
    from before its restart (the ground's "OPM off", 14 s old, after its "OPM on"). So a
    live command signed before `floor_ns` (the receiving process's start, by its own
    clock) is refused: it was meant for an earlier run of this process, or is a replay.
    A command reaches a process only while it is subscribed, so a genuine one is never
    older than it (clocks agreeing: GPS or NTP time).

    The marks are kept per `receiver` (a subscription, a queryable): one message reaches
    every subscription of a process whose key expression it matches (a recorder's
    `{prefix}/**` and the bus's own digest subscription both hear a UAV's digest), and
    each must believe it once. With one mark per process, whichever subscription Zenoh
    called first used the message up and the other refused it as replayed.
    """

    def __init__(self, window_ns: int = DEFAULT_WINDOW_NS, floor_ns: int = 0) -> None:
        self.window_ns = window_ns
        self.floor_ns = floor_ns
        self._marks: OrderedDict[tuple[int, str, str], int] = OrderedDict()
        self._missions: OrderedDict[str, int] = OrderedDict()

    def check(
        self, key: str, envelope: Envelope, how: Delivery, now_ns: int, receiver: int = 0
    ) -> Refusal | None:
        """None (and the message remembered for `receiver`) if fresh, else why not."""
        stamp = envelope.stamp_ns
        if stamp > now_ns + self.window_ns:
            return Refusal.STALE  # from the future: a skewed clock, or a forgery kept for later
        space = space_of(key)
        parsed = space.parse(key) if space is not None else None
        mission = parsed.mission if parsed is not None else None
        if parsed is not None and mission is not None and parsed.spec.role is Role.COMMAND:
            targets_at = self._missions.get(mission)
            if parsed.spec is TARGETS:
                self._remember_mission(mission, stamp)
            elif targets_at is not None and stamp < targets_at - self.window_ns:
                # An abort made before its mission was sent (a window's slack for the
                # clocks of two ground stations): from before a restart reused the id.
                return Refusal.REPLAYED
        if how is Delivery.REPLY:
            if parsed is not None and parsed.spec is STATE and now_ns - stamp > self.window_ns:
                # A state says how its UAV is now: an old one replayed would show a UAV
                # that has landed (or gone) as flying, and vouch for a ghost token.
                return Refusal.STALE
            return None  # a caught-up message is old by nature; its key binds it
        if now_ns - stamp > self.window_ns:
            return Refusal.STALE
        if stamp < self.floor_ns and parsed is not None and parsed.spec.role is Role.COMMAND:
            return Refusal.REPLAYED  # signed before this process started
        mark = (receiver, envelope.author, key)
        last = self._marks.get(mark)
        if last is not None and stamp <= last:
            return Refusal.REPLAYED
        self._marks[mark] = stamp
        self._marks.move_to_end(mark)
        self._prune(now_ns)
        return None

    def _remember_mission(self, mission: str, stamp: int) -> None:
        # The first signing of a mission: its server may sign it again for each query.
        self._missions[mission] = min(stamp, self._missions.get(mission, stamp))
        self._missions.move_to_end(mission)
        while len(self._missions) > MAX_MARKS:
            self._missions.popitem(last=False)

    def _prune(self, now_ns: int) -> None:
        # A mark older than the window guards nothing: such a message is stale anyway.
        while self._marks:
            oldest = next(iter(self._marks.values()))
            if now_ns - oldest <= self.window_ns and len(self._marks) <= MAX_MARKS:
                break
            self._marks.popitem(last=False)
