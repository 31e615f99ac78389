"""Zenoh's own log, cut to what an operator can act on.

Zenoh's Rust runtime writes its log to standard output in its own format (coloured, one
line per event, Rust module paths), out of Python's reach; it is on in a secure router
(fleet/transport/router.py turns on its warnings: they name each link it refused), and
in any program when $RUST_LOG is set. Left as it is, a router's terminal fills with
lines nobody can act on: a sample that raced its subscription's undeclaration
("Received Data for unknown key_expr"), a mesh router retrying a peer that is
restarting, and one line per refused link, which the refusal watch already counts and
sums up (`refused links so far: no_certificate=2`).

`ZenohLog.keep` is given each line the process writes there (`FdTap`'s gate): a line
that is not Zenoh's passes on untouched; one of Zenoh's is logged again through
Python's `logging`, on the logger `zenoh.<its Rust module>`, at the level `level_of`
gives it, with its text only (no colours, no Rust source paths), and not passed on.
So at a program's default verbosity an operator sees Zenoh's warnings and errors, less
the known benign ones; `-v` shows those too (DEBUG); with $RUST_LOG set, every line
passes on exactly as Zenoh wrote it (the user asked for Zenoh's own log).
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass

from fleet.transport.link_refusal import classify

#: The environment variable Zenoh reads its log filter from.
RUST_LOG_ENV = "RUST_LOG"

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: tracing's line: time, level, then the thread's name and id and any spans, then the
#: Rust module (target), a colon, and the message.
_LINE = re.compile(
    r"^(?P<time>\d{4}-\d\d-\d\dT[\d:.]+Z)\s+(?P<level>TRACE|DEBUG|INFO|WARN|ERROR)\s+"
    r"(?:\S+\s+)*?(?P<target>[a-z_][a-z0-9_]*(?:::[a-z0-9_]+)*):\s(?P<message>.*)$"
)
_RUST_LOCATION = re.compile(r"\s+at \S+\.rs:\d+\.?")
_LEVELS = {
    "TRACE": logging.DEBUG,
    "DEBUG": logging.DEBUG,
    # Zenoh's own progress reports (its access control's "granted"/"denied" notes):
    # what the fleet's own log says for an operator, in its words.
    "INFO": logging.DEBUG,
    "WARN": logging.WARNING,
    "ERROR": logging.ERROR,
}

#: (Rust module, words in the message): warnings and errors nothing is wrong behind,
#: or that pass by themselves. Logged at DEBUG (`-v`).
BENIGN: tuple[tuple[str, str], ...] = (
    # A sample or query that arrived for a subscription or queryable being undeclared:
    # a race Zenoh resolves by dropping it.
    ("zenoh::api::session", "for unknown key_expr"),
    # A mesh router retrying a peer (a restart, a UAV's router not up yet): it retries by
    # itself; the fleet's own log says which UAV is missing.
    ("zenoh::net::runtime::orchestrator", "Unable to connect to"),
)


@dataclass(frozen=True)
class ZenohLine:
    level: str  #: TRACE, DEBUG, INFO, WARN or ERROR, as Zenoh wrote it
    target: str  #: the Rust module that logged it: zenoh::api::session
    message: str  #: its text, without Rust source paths


def parse(line: str) -> ZenohLine | None:
    """The Zenoh log line `line` is, or None if it is none (colours ignored)."""
    found = _LINE.match(_ANSI.sub("", line))
    if found is None:
        return None
    message = _RUST_LOCATION.sub("", found["message"]).strip()
    return ZenohLine(found["level"], found["target"], message)


def level_of(line: ZenohLine, raw: str = "") -> int:
    """The Python logging level Zenoh's `line` (as written: `raw`) is logged at for an
    operator: its own level for a warning or an error, DEBUG for a known benign one, for
    a refused link (the refusal watch counts it and logs the totals) and for anything
    below a warning."""
    if any(line.target.startswith(module) and words in line.message for module, words in BENIGN):
        return logging.DEBUG
    if classify(raw or f"{line.level} {line.target}: {line.message}") is not None:
        return logging.DEBUG
    return _LEVELS[line.level]


def logger_name(target: str) -> str:
    """The Python logger of a Rust module: zenoh::api::session -> zenoh.api.session (a
    dependency's, under zenoh: rustls::conn -> zenoh.rustls.conn)."""
    name = target.replace("::", ".")
    return name if name == "zenoh" or name.startswith(("zenoh.", "zenoh_")) else f"zenoh.{name}"


class ZenohLog:
    """The gate of the output Zenoh writes its log to (`FdTap`'s `keep`)."""

    def __init__(self, raw: bool | None = None) -> None:
        #: Pass Zenoh's lines on as written ($RUST_LOG set: the user asked for them).
        self.raw = bool(os.environ.get(RUST_LOG_ENV)) if raw is None else raw

    def keep(self, text: str) -> bool:
        """Whether `text`, a line written to the output, passes on as it is; a line of
        Zenoh's that does not is logged through Python's logging instead."""
        if self.raw:
            return True
        line = parse(text)
        if line is None:
            return True
        logging.getLogger(logger_name(line.target)).log(level_of(line, text), "%s", line.message)
        return False
