"""Which connections a secure router refused, read from Zenoh's own log lines.

Zenoh refuses a TLS link (no client certificate, one from another CA, an expired one)
inside its Rust runtime and tells Python nothing; it only writes a warning to its log, on
standard output (fleet/transport/router.py turns those on). `classify` recognises those lines, as
Zenoh 1.x words them (the samples in tests/transport/test_link_refusal.py were captured
from a real router), and `RefusedLinks` counts them by kind. Any other warning of the
TLS listener is a refusal of no known kind (`TLS_OTHER`); any other line is none.
"""

from __future__ import annotations

import re
import threading
from collections import Counter
from enum import Enum

#: Terminal colour codes: Zenoh colours its log even into a pipe.
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: The Rust module that logs a refused TLS handshake, and the one that logs an identity
#: the access control grants nothing (a revoked one, or one with no role in the fleet).
_TLS_TARGET = "zenoh_link_tls"
_ACL_TARGET = "access_control"


class LinkRefusal(Enum):
    """Why a router refused a link; counted under its value."""

    NO_CERTIFICATE = "no_certificate"  #: the client presented none
    UNKNOWN_CA = "unknown_ca"  #: its certificate was not signed by the fleet's CA
    EXPIRED = "expired"  #: its certificate has expired or is not valid yet
    BAD_CERTIFICATE = "bad_certificate"  #: its certificate was refused for another reason
    PEER_REFUSED = "peer_refused"  #: the client refused the router's certificate
    TLS_OTHER = "tls_other"  #: another TLS warning (a handshake cut short, ...)
    NO_RIGHTS = "no_rights"  #: a link was opened, but its identity is granted nothing
    #: a link of an identity revoked while the router ran, closed by the router
    #: (`fleet.transport.live_revocation`; counted there, not read from Zenoh's log)
    REVOKED = "revoked"


#: (text in the message, kind), the first match wins; all under the TLS target.
_TLS_KINDS: tuple[tuple[str, LinkRefusal], ...] = (
    ("peer sent no certificates", LinkRefusal.NO_CERTIFICATE),
    ("invalid peer certificate: certificate expired", LinkRefusal.EXPIRED),
    ("invalid peer certificate: certificate not valid yet", LinkRefusal.EXPIRED),
    ("invalid peer certificate: BadSignature", LinkRefusal.UNKNOWN_CA),
    ("invalid peer certificate: UnknownIssuer", LinkRefusal.UNKNOWN_CA),
    ("invalid peer certificate", LinkRefusal.BAD_CERTIFICATE),
    ("received fatal alert", LinkRefusal.PEER_REFUSED),
)
_WARNING = re.compile(r"\bWARN\b")
_NO_SUBJECT = "did not match any configured ACL subject"


def classify(line: str) -> LinkRefusal | None:
    """The kind of link refusal Zenoh's log `line` reports, or None if it reports none."""
    text = _ANSI.sub("", line)
    if _TLS_TARGET in text and _WARNING.search(text):
        return next((kind for needle, kind in _TLS_KINDS if needle in text), LinkRefusal.TLS_OTHER)
    if _ACL_TARGET in text and _NO_SUBJECT in text:
        return LinkRefusal.NO_RIGHTS
    return None


class RefusedLinks:
    """Counts of refused links by kind (thread-safe: the log reader counts, others read)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._counts: Counter[LinkRefusal] = Counter()

    def count(self, kind: LinkRefusal) -> int:
        """Count one refusal of `kind`; the new count of that kind."""
        with self._lock:
            self._counts[kind] += 1
            return self._counts[kind]

    def counts(self) -> dict[str, int]:
        """The counts so far by kind's value, in the order of `LinkRefusal`."""
        with self._lock:
            return {kind.value: self._counts[kind] for kind in LinkRefusal if self._counts[kind]}

    def summary(self) -> str:
        """`no_certificate=2 unknown_ca=1` (kinds never seen left out), or `none`."""
        counts = self.counts()
        return " ".join(f"{kind}={n}" for kind, n in counts.items()) or "none"
