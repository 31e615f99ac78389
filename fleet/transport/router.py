"""An embedded Zenoh router: a router-mode session in this Python process.

No `zenohd` binary is on PyPI, but a Python session can run in router mode
(docs/architecture.md), so `fleet up` and the tests need nothing but the wheel. The router
routes between client-mode sessions (the star every fleet process joins by default) and
serves its admin space (`@/**`) to stock tools.

With a `SecureProfile` (`--secure DIR`) it listens with mutual TLS and enforces the
fleet's access policy (docs/security.md), counts the links it refused and answers
`{prefix}/router/state` with the counts (`ground-cli routers`).

A listen endpoint on port 0 (`tcp/127.0.0.1:0`) takes a port the OS picks, free when it
is bound, so no one races for it: `Router.endpoints` says which (read back from the
router's admin space, `@/ZID/router`, whose `locators` are what it listens on).

`python -m fleet.transport.router --listen tcp/127.0.0.1:7447` runs one until SIGTERM or
Ctrl-C; once it listens, it prints `router listening on ENDPOINT` (one line per endpoint,
the port it bound).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import threading
import time
from pathlib import Path
from typing import Self

import zenoh

from fleet.errors import CertError, FleetError
from fleet.mission.access import ROUTER
from fleet.mission.messages import RouterState
from fleet.mission.signature import sign
from fleet.transport import refusal_watch, zenoh_exit
from fleet.transport.bus import Bus
from fleet.transport.bus_codec import ENCODING, encode
from fleet.transport.cli import (
    ExitCode,
    add_key_prefix_argument,
    add_verbose_argument,
    fail,
    setup_logging,
    stop_on_signals,
)
from fleet.transport.link_cut import address_of, cut_accepted
from fleet.transport.link_refusal import LinkRefusal
from fleet.transport.live_revocation import RevocationGuard
from fleet.transport.secure import SecureProfile
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import DEFAULT_ROUTER, error_text, make_config

log = logging.getLogger(__name__)

#: What `python -m fleet.transport.router` prints before each endpoint it listens on.
LISTENING = "router listening on "
#: How long the router's own admin space may take to say what it listens on, seconds.
_ADMIN_TIMEOUT_S = 5.0


def parse_listening(line: str) -> str | None:
    """The endpoint of a `router listening on ENDPOINT` line; None for any other line."""
    line = line.strip()
    return line.removeprefix(LISTENING) if line.startswith(LISTENING) else None


def _split(endpoint: str) -> tuple[str, str, str, str]:
    """`tcp/127.0.0.1:7447#iface=lo` -> ("tcp", "127.0.0.1", "7447", "#iface=lo")."""
    proto, _, rest = endpoint.partition("/")
    address, hash_, options = rest.partition("#")
    host, _, port = address.rpartition(":")
    return proto, host, port, hash_ + options


def bound_endpoints(session: zenoh.Session, listen: list[str]) -> list[str]:
    """`listen` with each port 0 replaced by the port `session` (a router's, with its admin
    space on) bound there: read from its admin space, the only place Zenoh says it.

    An endpoint on a wildcard address (`0.0.0.0`) is listed once per interface, all on
    the port it bound: any of them tells the port. Raises RouterError if the admin space
    does not answer or lists no locator for an endpoint asked on port 0.
    """
    if all(_split(endpoint)[2] != "0" for endpoint in listen):
        return list(listen)
    locators: list[str] = []
    for reply in session.get(f"@/{session.zid()}/router", timeout=_ADMIN_TIMEOUT_S):
        if reply.ok is not None:
            with_locators = json.loads(reply.ok.payload.to_bytes())
            locators += [str(locator) for locator in with_locators.get("locators", [])]
    bound = []
    for endpoint in listen:
        proto, host, port, options = _split(endpoint)
        if port != "0":
            bound.append(endpoint)
            continue
        same = [_split(locator) for locator in locators if locator.startswith(f"{proto}/")]
        exact = [where for where in same if where[1] == host] or same
        if not exact:
            raise RouterError(
                f"the router listens on {endpoint} but its admin space lists no {proto} "
                f"locator (it lists {', '.join(locators) or 'none'})"
            )
        bound.append(f"{proto}/{host}:{exact[0][2]}{options}")
    return bound


#: Zenoh's own log: its warnings name each link it refused (no certificate, an unknown
#: CA, an expired certificate), which Python never sees otherwise, and its access control
#: says (at info) when an identity is granted nothing. RUST_LOG overrides it. Its lines
#: reach the process's log cut to what an operator can act on (`zenoh_log`).
ZENOH_LOG_LEVEL = "warn,zenoh::net::routing::interceptor::access_control=info"
_zenoh_log_on = False


def _log_refused_links() -> None:
    """Turn on Zenoh's warnings, on standard output (once per process: its logger is global)."""
    global _zenoh_log_on
    if not _zenoh_log_on:
        zenoh.init_log_from_env_or(ZENOH_LOG_LEVEL)
        _zenoh_log_on = True


def listen_problem(error: BaseException) -> str:
    """What went wrong listening, in a line, and what to do about it."""
    text = error_text(error)
    if "Address already in use" in text:
        return (
            "the address is in use (another router or `fleet up` listens there): stop it, "
            "or listen on another port"
        )
    return text


class RouterError(FleetError, RuntimeError):
    """The router could not open (typically: its listen endpoint is taken or malformed)."""


class Router:
    """A router-mode Zenoh session listening on `listen`, optionally meshed via `connect`.

    Use as a context manager; the session is closed on exit whatever happened inside.
    """

    def __init__(
        self,
        listen: list[str],
        connect: list[str] | None = None,
        secure: SecureProfile | None = None,
    ) -> None:
        if not listen:
            raise ValueError("a router needs at least one listen endpoint")
        self.listen = list(listen)
        self.connect = list(connect or [])
        self.secure = secure
        self._session: zenoh.Session | None = None
        self._watch: refusal_watch.RefusalWatch | None = None
        self._guard: RevocationGuard | None = None
        #: What it listens on, each port 0 replaced by the port bound (once open).
        self.endpoints: list[str] = list(listen)

    @property
    def refused_links(self) -> dict[str, int]:
        """The links refused so far in this process by kind (`LinkRefusal`'s values); empty
        for an open router, which refuses none."""
        return self._watch.links.counts() if self._watch is not None else {}

    @property
    def session(self) -> zenoh.Session:
        if self._session is None:
            raise RuntimeError("the router is not open")
        return self._session

    def bus(self) -> Bus:
        """A bus on the router's own session, which stays the router's: closing the bus
        leaves it open (the launcher watches a fleet start through it)."""
        return ZenohBus(self.session, owns_session=False)

    @property
    def zid(self) -> str:
        return str(self.session.zid())

    def open(self) -> None:
        if self._session is not None:
            return
        try:
            config = make_config("router", self.connect, self.listen)
            if self.secure is not None:
                self.secure.apply_to_router(config)
                _log_refused_links()
                self._watch = refusal_watch.acquire()
            self._session = zenoh.open(config)
            zenoh_exit.close_at_exit(self.close)  # if never closed (fleet.transport.zenoh_exit)
            self.endpoints = bound_endpoints(self._session, self.listen)
            if self.secure is not None:
                self._serve_state(self.secure.key_space.router_state())
                self._guard_revocations(self.secure)
        except zenoh.ZError as error:
            self.close()
            raise RouterError(
                f"cannot start a Zenoh router on {', '.join(self.listen)}: {listen_problem(error)}"
            ) from error
        except RouterError:
            self.close()
            raise
        log.info("zenoh router %s listening on %s", self.zid, ", ".join(self.endpoints))

    def _serve_state(self, key: str) -> None:
        """Answer `key` (`ground-cli routers`) with this router's refused links, signed by
        this router's own identity (when the fleet has signing keys) and bound to the
        query's challenge: a router answers for itself, and for no other."""
        signing = self.secure.signing_key() if self.secure is not None else None

        def answer(query: zenoh.Query) -> None:
            asked = query.payload.to_bytes() if query.payload is not None else b""
            challenge = asked.decode("ascii", "replace")[:64] if asked else None
            payload = encode(RouterState(self.zid, self.refused_links, challenge))
            attachment = None
            if signing is not None and self.secure is not None:
                name = self.secure.router_name
                attachment = sign(signing, name, key, payload, time.time_ns())
            query.reply(key, payload, encoding=ENCODING, attachment=attachment)

        self.session.declare_queryable(key, answer)

    def _guard_revocations(self, secure: SecureProfile) -> None:
        """Close the links of identities revoked while this router runs (its access
        control, built now, leaves out those revoked before)."""
        watch = self._watch

        def count() -> None:
            if watch is not None:
                watch.count(LinkRefusal.REVOKED)

        self._guard = RevocationGuard(
            self.session,
            secure.key_space.roster(),
            secure.identity(secure.router_name).ca,
            secure.revoked,
            on_cut=count,
        )
        self._guard.start()

    @property
    def revocations(self) -> RevocationGuard | None:
        """What this router does about revocations heard while it runs (secure only)."""
        return self._guard

    def close(self) -> None:
        guard, self._guard = self._guard, None
        if guard is not None:
            guard.let_go()
        session, self._session = self._session, None
        if session is not None:
            try:
                session.close()
            finally:
                self._end_accepted()
        if guard is not None:
            guard.stop()
        self._release_watch()

    def _end_accepted(self) -> None:
        """End the connections still open on the closed listeners: one Zenoh accepted as
        the session closed outlives the close, its client connected to no router
        (`fleet.transport.link_cut`; a revoked client redials many times a second)."""
        for endpoint in self.endpoints:
            local = address_of(endpoint)
            if local is None or local.port == 0:
                continue  # not a stream listener, or never bound
            ended = cut_accepted(local)
            if ended:
                log.info("ended %d connection(s) accepted on %s as it closed", ended, endpoint)

    def _release_watch(self) -> None:
        watch, self._watch = self._watch, None
        if watch is not None:
            refusal_watch.release()

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m fleet.transport.router", description="Run an embedded Zenoh router."
    )
    parser.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help=f"endpoint to listen on (repeatable; default {DEFAULT_ROUTER}; port 0: a free "
        "port, printed once bound)",
    )
    parser.add_argument(
        "--connect", action="append", metavar="ENDPOINT", help="another router to mesh with"
    )
    parser.add_argument(
        "--secure",
        type=Path,
        metavar="DIR",
        help="mutual TLS and access control with the identities in DIR (`fleet certs make`)",
    )
    parser.add_argument(
        "--identity",
        default=ROUTER,
        metavar="NAME",
        help="with --secure: the identity in DIR this router presents (default %(default)s; "
        "a UAV's own router: router-N)",
    )
    add_key_prefix_argument(parser)  # the keys the access control covers
    add_verbose_argument(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose)
    stop = threading.Event()
    try:
        secure = (
            SecureProfile.load(args.secure, args.key_space, args.identity)
            if args.secure is not None
            else None
        )
        router = Router(args.listen or [DEFAULT_ROUTER], args.connect, secure)
        with stop_on_signals(stop.set), router:
            for endpoint in router.endpoints:
                print(f"{LISTENING}{endpoint}", flush=True)
            # A bounded wait in a loop, so the signal handler runs promptly.
            while not stop.wait(0.5):
                pass
    except (RouterError, CertError) as error:
        return fail("error", str(error))
    return ExitCode.OK


if __name__ == "__main__":
    sys.exit(main())
