"""A secure router closes the links of an identity revoked while it runs, and keeps
closing them.

A router's access control is built from the roster when it starts, and Zenoh 1.x
changes neither it nor its TLS trust while running (no call for it; a configuration
change through the admin space reaches plugins only), and its Python API cannot close a
link. So `RevocationGuard`, on the router's own session:

* hears the roster (`{prefix}/roster`, put by `fleet certs revoke`) and believes it only
  if the fleet's CA signed it; revocations only accumulate;
* closes at once every open link whose certificate names a newly revoked identity
  (`Link.auth_identifier`, the common name): the socket is shut down under Zenoh
  (`fleet.transport.link_cut`), which then drops the link and its transport;
* closes each new link of a revoked identity before Zenoh reads a byte of it. Zenoh
  calls a direct link-event callback after the transport is established and before it
  starts reading the link, so nothing the revoked client sends is routed. The client
  dials again the moment its link ends, so the link is first *held* (`HOLD_S`, while
  the client thinks it is connected and the router reads nothing) and then cut: one
  handshake per `HOLD_S` instead of hundreds a second. At most `MAX_HELD` links are
  held at once (each holds one of Zenoh's blocking threads); more are cut at once.

Identities revoked before the router started are left to its access control (their links
stay open, granted nothing). A link on a datagram protocol (udp/, quic/) cannot be cut
(its socket is shared); the secure profile listens on tls/.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zenoh

from fleet.files.signers import RosterError, roster_of
from fleet.transport.link_cut import address_of, cut

log = logging.getLogger(__name__)

#: How long a revoked identity's new link is held (read from by no one) before it is cut.
#: Below a client's lease (10 s by default), past which the client gives up on its own.
HOLD_S = 5.0
#: Links held at once, at most; the next ones are cut at once.
MAX_HELD = 8
#: How long stop() waits for held links to be let go before the session closes anyway.
RELEASE_WAIT_S = 10.0
#: Reconnections refused are logged this many times, then every LOG_EVERY-th time.
LOG_FIRST = 10
LOG_EVERY = 100


class RevocationGuard:
    """Closes the links of identities revoked on `roster_key` (CA in `ca_pem`) after the
    start; `acl_revoked` are those the router's access control already leaves out.
    `on_cut` is called once per link cut (to count it). Thread-safe: Zenoh calls in."""

    def __init__(
        self,
        session: zenoh.Session,
        roster_key: str,
        ca_pem: Path,
        acl_revoked: frozenset[str] = frozenset(),
        *,
        on_cut: Callable[[], object] = lambda: None,
        hold_s: float | None = None,
        max_held: int = MAX_HELD,
    ) -> None:
        self.session = session
        self.roster_key = roster_key
        self.ca_pem = ca_pem
        self.acl_revoked = acl_revoked
        self.hold_s = HOLD_S if hold_s is None else hold_s  # read now: a test shortens it
        self.max_held = max_held
        self._on_cut = on_cut
        self._lock = threading.Lock()
        #: Signalled when a held link is let go, so stop() can wait for the last one.
        self._released = threading.Condition(self._lock)
        self._revoked: frozenset[str] = frozenset()
        self._held = 0
        self._refused = 0
        self._closed = 0
        self._stop = threading.Event()
        self._declared: list[Any] = []

    @property
    def revoked(self) -> frozenset[str]:
        """The identities revoked since the start (whose links this guard cuts)."""
        return self._revoked

    @property
    def closed(self) -> int:
        """Open links cut when their identity was revoked."""
        return self._closed

    @property
    def held(self) -> int:
        """New links of a revoked identity being held now (to be cut)."""
        return self._held

    @property
    def refused(self) -> int:
        """New links of a revoked identity cut."""
        return self._refused

    def start(self) -> None:
        # Direct callbacks: run on Zenoh's thread, so a new link is cut before it is read.
        on_link = zenoh.handlers.Callback(self._on_link, indirect=False)
        on_roster = zenoh.handlers.Callback(self._on_roster, indirect=False)
        self._declared = [
            self.session.info.declare_link_events_listener(on_link),
            self.session.declare_subscriber(self.roster_key, on_roster),
        ]

    def let_go(self) -> None:
        """Cut a link being held now, let it go before this returns, and from now on cut
        a revoked identity's new link at once, unheld.

        A held link keeps one of Zenoh's threads in `_on_link`: closing the session
        while it is still there timed out on a loaded box, so wait (bounded) for it. The
        listener stays declared: a revoked client redials the moment its link is cut,
        and a link accepted between an undeclare and the session's close was let in."""
        self._stop.set()
        with self._released:
            self._released.wait_for(lambda: self._held == 0, timeout=RELEASE_WAIT_S)

    def stop(self) -> None:
        """Let go of held links and stop listening (after the session's close: see
        `let_go`)."""
        self.let_go()
        declared, self._declared = self._declared, []
        for declaration in declared:
            with contextlib.suppress(zenoh.ZError):  # the session is closed already
                declaration.undeclare()

    # ---- revocation --------------------------------------------------------------------
    def revoke(self, names: frozenset[str], source: str) -> frozenset[str]:
        """Revoke `names` (heard from `source`): each one's open links are cut now and its
        new ones from now on. Returns the identities newly revoked."""
        with self._lock:
            new = names - self._revoked - self.acl_revoked
            self._revoked = self._revoked | new
        if not new:
            return new
        log.warning("revoked from now on (%s): %s", source, ", ".join(sorted(new)))
        try:
            links = self.session.info.links()
        except zenoh.ZError:
            return new  # closing
        for link in links:
            if link.auth_identifier in new and self._cut(link):
                with self._lock:
                    self._closed += 1
                log.warning("closed %s's link from %s: revoked", link.auth_identifier, link.dst)
        return new

    def _on_roster(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        try:
            document = json.loads(sample.payload.to_bytes())
            if not isinstance(document, dict):
                raise RosterError(f"{key}: not a roster")
            heard = roster_of(document, self.ca_pem, key)
        except (ValueError, RecursionError, RosterError) as error:
            log.warning("refused a roster on %s: %s", key, error)
            return
        self.revoke(heard.revoked, f"a roster heard on {key}")

    # ---- links -------------------------------------------------------------------------
    def _on_link(self, event: zenoh.LinkEvent) -> None:
        # On Zenoh's thread, before it reads the link: what runs here decides whether a
        # byte of it is routed.
        if event.kind != zenoh.SampleKind.PUT:
            return
        link = event.link
        if link.auth_identifier is None or link.auth_identifier not in self._revoked:
            return
        with self._lock:
            hold = self._held < self.max_held and not self._stop.is_set()
            if hold:
                self._held += 1
        try:
            if hold:
                self._stop.wait(self.hold_s)
            cut_now = self._cut(link)
        finally:
            if hold:
                with self._released:
                    self._held -= 1
                    self._released.notify_all()
        if cut_now:
            with self._lock:
                self._refused += 1
                count = self._refused
            if count <= LOG_FIRST or count % LOG_EVERY == 0:
                log.warning(
                    "refused a link of %s (revoked) from %s (%d so far)",
                    link.auth_identifier, link.dst, count,
                )  # fmt: skip

    def _cut(self, link: zenoh.Link) -> bool:
        local, peer = address_of(link.src), address_of(link.dst)
        if local is None or peer is None:
            log.warning(
                "cannot close %s's link %s -> %s: not a stream link",
                link.auth_identifier, link.dst, link.src,
            )  # fmt: skip
            return False
        if not cut(local, peer):
            return False
        self._on_cut()
        return True
