"""Signed commands on the Zenoh bus: what a process signs, relays and refuses.

In the secure profile (a Zenoh config with mutual TLS whose CA directory holds the
fleet's roster of signers, `fleet.files.signers`), every `ZenohBus` carries a
`BusSigning`: the process's identity (its certificate's common name), its own Ed25519
key and the roster. Then

* each message it authors on a signed key (`fleet.mission.signature.SIGNED_KEYS`) is
  put, replied or asked with a signature envelope in the Zenoh attachment;
* a message it relays (a UAV answering a teammate's catch-up with the ground's targets
  or abort) is replied with the author's original payload and envelope, remembered as
  it arrived: the relay's own signature would not make it the ground's;
* every message on a signed key that reaches it (a publication, a reply, a command
  query) is checked: the author's signature, the author's right to that key (the key
  registry the ACL is derived from), the roster's revocations and freshness. A refused
  message never reaches the process; it is logged (rate-limited) and counted in
  `bus_codec.DROPPED` by reason (an onboard's state shows them as `bus_unsigned`, ...).

Without a roster (the open profile) nothing is signed or checked.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable
from pathlib import Path

import zenoh
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from fleet.files.certs import common_name
from fleet.files.signers import (
    ROSTER_FILE,
    RosterError,
    load_roster,
    load_signing_key,
    roster_of,
    signing_key_path,
)
from fleet.mission.key_space import space_of
from fleet.mission.signature import (
    DEFAULT_WINDOW_NS,
    Delivery,
    Freshness,
    Refusal,
    Roster,
    author_of,
    sign,
    verify,
)
from fleet.transport import bus_codec
from fleet.transport.refusal_log import RefusalLog

log = logging.getLogger(__name__)
#: Stale replies, each said with its age, at most every few seconds (a replayer cannot
#: fill the log); every one is counted as `stale` too.
_stale_replies = RefusalLog(log)

#: Keys whose signed messages are remembered to relay with their author's envelope.
RELAY_CACHE = 1024
#: Distinct messages remembered per key (the latest): a rival ground's mission under
#: the same id must not take the place of the one this UAV holds and relays.
RELAY_PER_KEY = 4
#: Each refusal reason is logged this many times, then every LOG_EVERY-th time.
LOG_FIRST = 10
LOG_EVERY = 1000


class BusSigning:
    """Signs what this identity authors, relays what others signed, checks what arrives.

    Thread-safe: Zenoh calls `check` from its own threads.
    """

    def __init__(
        self,
        identity: str,
        key: Ed25519PrivateKey,
        roster: Roster,
        *,
        window_ns: int = DEFAULT_WINDOW_NS,
        clock: Callable[[], int] = time.time_ns,
        ca_pem: Path | None = None,
    ) -> None:
        self.identity = identity
        self._key = key
        self.roster = roster
        #: The CA a roster heard on the bus must be signed by (None: none is believed).
        self._ca_pem = ca_pem
        self._clock = clock
        self._lock = threading.Lock()
        # A live command signed before this process started is refused (a replay across
        # its restart: the marks are in memory).
        self._freshness = Freshness(window_ns, floor_ns=clock())
        #: The envelopes of the latest signed messages per key (by payload), as put by us
        #: or received: a reply with one of those payloads passes its envelope on, so a
        #: message keeps its author's signature and first time.
        self._signed: OrderedDict[str, dict[bytes, bytes]] = OrderedDict()
        self._refused: Counter[Refusal] = Counter()
        self._last_stamp = 0

    @classmethod
    def from_config(cls, config: zenoh.Config) -> BusSigning | None:
        """The signing of the identity a Zenoh config presents, or None when the config is
        not the secure profile's (no TLS client identity, or no roster beside its CA).

        Raises RosterError (or CertError) when the roster or the key is there but cannot
        be believed: a secure process never falls back to unsigned.
        """
        try:
            tls = json.loads(config.get_json("transport/link/tls"))
        except (zenoh.ZError, TypeError, ValueError):  # no such section
            return None
        if not isinstance(tls, dict):
            return None
        ca, certificate = tls.get("root_ca_certificate"), tls.get("connect_certificate")
        if not isinstance(ca, str) or not isinstance(certificate, str):
            return None
        ca_path, certificate_path = Path(ca), Path(certificate)
        roster_dir = ca_path.parent
        if not (roster_dir / ROSTER_FILE).is_file():
            log.warning(
                "%s: no roster of signers: commands are neither signed nor checked "
                "(make the identities again with `fleet certs make`)",
                roster_dir,
            )
            return None
        roster = load_roster(roster_dir, ca_path)
        identity = common_name(certificate_path)
        key = load_signing_key(signing_key_path(certificate_path.parent, identity))
        if identity in roster.revoked:
            log.warning("this identity (%s) is revoked: its messages will be refused", identity)
        log.info("signing as %s; %d signers, %d revoked", identity, len(roster.keys),
                 len(roster.revoked))  # fmt: skip
        return cls(identity, key, roster, ca_pem=ca_path)

    # ---- outgoing ---------------------------------------------------------------------
    def _stamp(self) -> int:
        # Strictly increasing, so two messages on one key never share a timestamp.
        with self._lock:
            self._last_stamp = max(self._clock(), self._last_stamp + 1)
            return self._last_stamp

    def _sign(self, key: str, payload: bytes) -> bytes:
        return sign(self._key, self.identity, key, payload, self._stamp())

    def attachment(self, key: str, payload: bytes, how: Delivery) -> bytes | None:
        """The envelope for a put (or a command query) this process authors on `key`."""
        space = space_of(key)
        if space is None or author_of(space, key, how) is None:
            return None
        envelope = self._sign(key, payload)
        if how is Delivery.PUT:
            self._remember(key, payload, envelope)
        return envelope

    def _remember(self, key: str, payload: bytes, envelope: bytes) -> None:
        with self._lock:
            known = self._signed.pop(key, {})
            known.pop(payload, None)  # re-inserted below as the latest
            known[payload] = envelope
            while len(known) > RELAY_PER_KEY:
                del known[next(iter(known))]
            self._signed[key] = known
            if len(self._signed) > RELAY_CACHE:
                self._signed.popitem(last=False)

    def keep(self, key: str, payload: bytes, attachment: bytes) -> None:
        """A message heard on `key` kept to relay as it arrived (`ZenohBus.keep_latest`),
        its envelope not checked: whoever it is relayed to checks it."""
        self._remember(key, payload, attachment)

    def latest(self, key: str) -> bytes | None:
        """The payload of the latest message remembered on `key`, if any."""
        with self._lock:
            known = self._signed.get(key)
            return next(reversed(known)) if known else None

    def _envelope_of(self, key: str, payload: bytes) -> bytes | None:
        """The envelope remembered for exactly this message, if any (kept as recent)."""
        with self._lock:
            known = self._signed.get(key)
            if known is None:
                return None
            self._signed.move_to_end(key)  # a message still relayed is kept
            return known.get(payload)

    def reply(self, key: str, payload: bytes) -> tuple[bytes, bytes | None]:
        """The payload and envelope of a reply on `key`: signed by us if ours, else the
        envelope this very message arrived with (a relay), else unsigned (and so refused).

        A relay passes on only the envelope of the payload it replies with: another
        message on that key (a rival ground's mission under the same id, heard after
        the one this UAV holds) is never handed over in its place.
        """
        space = space_of(key)
        author = author_of(space, key, Delivery.REPLY) if space is not None else None
        if author is None:
            return payload, None
        known = self._envelope_of(key, payload)
        if author == self.identity:
            # The message as put, with its first signature (a mission served while it
            # flies keeps the time it was sent), unless this is a new one.
            return payload, known if known is not None else self._sign(key, payload)
        if known is None:
            log.debug("no signed copy of this %s to relay: replied unsigned", key)
        return payload, known

    # ---- the roster, live -----------------------------------------------------------------
    def apply_roster(self, key: str, payload: bytes) -> frozenset[str]:
        """A roster heard on the bus (`fleet certs revoke` on a running fleet): if the CA
        signed it, its revocations are added to ours (never removed: an older roster
        replayed revives no one). Returns the identities newly revoked."""
        if self._ca_pem is None:
            return frozenset()
        try:
            document = json.loads(payload)
            if not isinstance(document, dict):
                raise RosterError(f"{key}: not a roster")
            heard = roster_of(document, self._ca_pem, key)
        except (ValueError, RecursionError, RosterError) as error:
            bus_codec.DROPPED.add(Refusal.BAD_SIGNATURE)
            log.warning("refused a roster on %s: %s", key, error)
            return frozenset()
        with self._lock:
            new = heard.revoked - self.roster.revoked
            if new:
                self.roster = Roster(self.roster.keys, self.roster.revoked | new)
        if new:
            log.warning(
                "revoked from now on (a roster heard on %s): %s", key, ", ".join(sorted(new))
            )
        if self.identity in new:
            log.warning(
                "this identity (%s) is revoked: its messages will be refused", self.identity
            )
        return new

    # ---- incoming ---------------------------------------------------------------------
    def check(
        self, key: str, payload: bytes, attachment: bytes, how: Delivery, receiver: int = 0
    ) -> bool:
        """Whether a message that arrived on `key` at `receiver` (a subscription, a
        queryable: each believes a message once, `Freshness`) may be believed (refusals
        counted)."""
        return self._checked(key, payload, attachment, how, receiver)[0]

    def check_reply(self, key: str, payload: bytes, attachment: bytes) -> tuple[bool, str | None]:
        """Whether a reply may be believed, and who signed it (None: a key not signed)."""
        return self._checked(key, payload, attachment, Delivery.REPLY)

    def _checked(
        self, key: str, payload: bytes, attachment: bytes, how: Delivery, receiver: int = 0
    ) -> tuple[bool, str | None]:
        space = space_of(key)
        if space is None:
            return True, None
        envelope, refusal = verify(self.roster, space, key, payload, attachment, how)
        if envelope is None and refusal is None:
            return True, None  # a key that is not signed
        if refusal is None and envelope is not None:
            with self._lock:
                now_ns = self._clock()
                refusal = self._freshness.check(key, envelope, how, now_ns, receiver)
            if refusal is Refusal.STALE and how is Delivery.REPLY:
                self._log_stale_reply(key, envelope.author, now_ns - envelope.stamp_ns)
        if refusal is None:
            if envelope is not None and envelope.author != self.identity:
                self._remember(key, payload, attachment)
            return True, envelope.author if envelope is not None else None
        self._refuse(key, refusal, envelope.author if envelope else None, how)
        return False, None

    def _log_stale_reply(self, key: str, author: str, age_ns: int) -> None:
        """Say why a signed reply was refused as stale: its age against the window (a
        state replayed from minutes ago, or a clock far off)."""
        window_s = self._freshness.window_ns / 1e9
        if age_ns < 0:
            when = f"{-age_ns / 1e9:.1f} s in the future"
        else:
            when = f"{age_ns / 1e9:.1f} s ago, older than the {window_s:g} s replay window"
        _stale_replies.warn(f"refused a reply on {key} signed by {author} {when} (a replay?)")

    def _refuse(self, key: str, refusal: Refusal, author: str | None, how: Delivery) -> None:
        bus_codec.DROPPED.add(refusal)
        with self._lock:
            self._refused[refusal] += 1
            count = self._refused[refusal]
        if count <= LOG_FIRST or count % LOG_EVERY == 0:
            log.warning(
                "refused %s on %s (signed by %s): %s (%d so far)",
                how.name.lower(), key, author or "nobody", refusal, count,
            )  # fmt: skip
