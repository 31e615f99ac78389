"""The Zenoh backend of `fleet.transport.bus.Bus`: one Zenoh session.

Every callback runs directly on the Zenoh thread that received the data
(`zenoh.handlers.Callback(..., indirect=False)`). zenoh-python's default runs each
subscription's, queryable's and query's callback in a Python thread of its own: 11
long-lived threads per onboard process, one more per query in flight, and a thread
hand-off per sample. The bus's callbacks only decode and queue (`fleet.transport.bus`:
they never wait), so they need no thread of their own. (`indirect` is marked unstable
in zenoh-python; the dependency is pinned to 1.10.)

A ground tool is a Zenoh *client* of one router (the star of docs/architecture.md): a
client needs no listen port and is relayed by the router to every UAV. `connect` opens
one and fails fast and clearly when nothing answers, never hangs: a refused connection
fails at once, and an endpoint that accepts TCP but never speaks Zenoh is given up after
`open_timeout_s` (Zenoh's own handshake timeout, 10 s by default, is shortened).

Opened with the secure profile's config, a bus signs (`fleet.transport.signing`): what
its identity writes on a command or decision key goes out with a signature in the Zenoh
attachment, what it relays goes out with its author's, and every signed message that
arrives (a sample, a reply, a command query) is checked before any callback sees it.
"""

from __future__ import annotations

import itertools
import json
import logging
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

import zenoh

from fleet.errors import CertError, FleetError, RosterError
from fleet.mission.access import uav_identity
from fleet.mission.delivery import Delivery
from fleet.mission.key_space import space_of
from fleet.mission.messages import StreamDigest
from fleet.transport import bus_codec, bus_qos, zenoh_exit
from fleet.transport.bus import (
    Bus,
    BusQuery,
    BusReply,
    BusSample,
    Declaration,
    PresenceCallback,
    Queryable,
    QueryNotify,
    RingSubscription,
    SampleCallback,
)
from fleet.transport.zenoh_config import (
    CONNECT_ENV,
    ZenohConfigError,
    check_endpoint,
    endpoints,
    error_text,
    has_tls_identity,
    make_config,
)

if TYPE_CHECKING:
    from fleet.mission.key_space import KeySpace
    from fleet.transport.signing import BusSigning
    from fleet.transport.stream_auth import StreamChecker, StreamSigner

log = logging.getLogger(__name__)

_T = TypeVar("_T")

#: Where a client connects: a router's endpoint, or a whole Zenoh config.
ClientTarget = str | zenoh.Config
#: How long opening may take against an endpoint that accepts but does not answer.
DEFAULT_OPEN_TIMEOUT_S = 3.0


class BusConnectError(FleetError, RuntimeError):
    """No Zenoh router could be reached at the endpoint (or the endpoint is malformed)."""


def direct(callback: Callable[[_T], Any]) -> zenoh.handlers.Callback[_T]:
    """`callback` run on the Zenoh thread that received the data, not a thread of its own."""
    return zenoh.handlers.Callback(callback, indirect=False)


def _attachment(data: zenoh.Sample | zenoh.Query) -> bytes:
    attachment = data.attachment
    return attachment.to_bytes() if attachment is not None else b""


def _plain(sample: zenoh.Sample) -> BusSample:
    """Key and payload only: what every subscription of the fleet reads."""
    return BusSample(str(sample.key_expr), sample.payload.to_bytes())


def sample_time_ns(timestamp: zenoh.Timestamp | None) -> int | None:
    """A Zenoh timestamp in ns since the epoch (None for none)."""
    if timestamp is None:
        return None
    moment = timestamp.get_time()
    return int(moment.timestamp()) * 1_000_000_000 + moment.microsecond * 1000


def _sample(sample: zenoh.Sample) -> BusSample:
    return BusSample(
        str(sample.key_expr),
        sample.payload.to_bytes(),
        str(sample.encoding),
        sample.kind == zenoh.SampleKind.DELETE,
        sample_time_ns(sample.timestamp),
    )


def _reply(reply: zenoh.Reply, author: str | None = None) -> BusReply:
    sample = reply.ok
    if sample is not None:
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        return BusReply(key, payload, True, str(sample.encoding), author)
    error = reply.err
    if error is None:  # neither: not produced by zenoh 1.x, kept for the type checker
        return BusReply("", b"", False, "")
    return BusReply("", error.payload.to_bytes(), False, str(error.encoding))


class ZenohQuery(BusQuery):
    def __init__(self, query: zenoh.Query, signing: BusSigning | None = None) -> None:
        self._query = query
        self._signing = signing
        self.key = str(query.key_expr)
        self.payload = query.payload.to_bytes() if query.payload is not None else b""
        self.parameters = str(query.parameters)

    def intersects(self, key: str) -> bool:
        return bool(self._query.key_expr.intersects(zenoh.KeyExpr(key)))

    def reply_bytes(self, key: str, payload: bytes) -> None:
        if self._signing is None:
            self._query.reply(key, payload, encoding=bus_codec.ENCODING)
            return
        payload, attachment = self._signing.reply(key, payload)
        self._query.reply(key, payload, encoding=bus_codec.ENCODING, attachment=attachment)

    def reply_err(self, text: str) -> None:
        self._query.reply_err(text.encode())

    def drop(self) -> None:
        self._query.drop()


class ZenohQueryable(Queryable):
    """Queries queued by a Zenoh callback, which then calls `notify`."""

    def __init__(
        self,
        session: zenoh.Session,
        key_expr: str,
        notify: QueryNotify | None,
        signing: BusSigning | None = None,
        receiver: int = 0,
    ) -> None:
        super().__init__(notify)
        self._signing = signing
        self._receiver = receiver
        self._queryable = session.declare_queryable(key_expr, direct(self._on_query))

    def _on_query(self, query: zenoh.Query) -> None:
        wrapped = ZenohQuery(query, self._signing)
        signing = self._signing
        if signing is not None and not signing.check(
            wrapped.key, wrapped.payload, _attachment(query), Delivery.QUERY, self._receiver
        ):
            wrapped.reply_err("refused: not a command its signer may give (signed commands)")
            wrapped.drop()
            return
        self.deliver(wrapped)

    def undeclare(self) -> None:
        self._queryable.undeclare()


class _ZenohRing:
    """Zenoh's own ring channel: the samples wait in Zenoh, converted (and their
    signatures checked) only when taken. In the secure profile a UAV's stream sample is
    believed as `subscribe` believes it, once its author's signed digest lists it: taken
    from the ring, it waits with the bus's `StreamChecker`, and comes out of `try_recv`
    once vouched for (`_believed`, at most `limit` of them, as in the ring)."""

    def __init__(self, bus: ZenohBus, key_expr: str, limit: int) -> None:
        self._bus = bus
        self._receiver = bus.new_receiver()
        self._believed: deque[BusSample] = deque(maxlen=limit)
        bus._watch_roster(key_expr)
        bus._watch_digests(key_expr)
        self._subscriber = bus.session.declare_subscriber(
            key_expr, zenoh.handlers.RingChannel(limit)
        )

    def try_recv(self) -> BusSample | None:
        while True:
            if self._believed:
                return self._believed.popleft()
            try:
                sample = self._subscriber.try_recv()
            except zenoh.ZError:  # the session closed under the subscriber
                return None
            if sample is None:
                return None
            received = self._bus._received(sample, Delivery.PUT, receiver=self._receiver)
            if received is not None:
                self._bus._believe(received, self._believed.append, self._receiver)

    def undeclare(self) -> None:
        self._subscriber.undeclare()


class ZenohBus(Bus):
    """A Bus over a Zenoh session, which it owns (closed by `close`)."""

    def __init__(
        self,
        session: zenoh.Session,
        signing: BusSigning | None = None,
        *,
        owns_session: bool = True,
    ) -> None:
        self.session = session
        #: False: the session is someone else's (an embedded router's), left open by `close`.
        self.owns_session = owns_session
        if owns_session:
            zenoh_exit.close_at_exit(self._close_session)
        #: The secure profile's signed commands (None: nothing signed or checked).
        self.signing = signing
        #: Declared publishers of the keys put at a steady rate (telemetry), by key.
        self._publishers: dict[str, zenoh.Publisher] = {}
        #: The roster subscriptions, one per key prefix this bus has used (secure only).
        self._rosters: dict[str, zenoh.Subscriber[None]] = {}
        self._rosters_lock = threading.Lock()
        #: Each subscription's and queryable's replay marks (`BusSigning.check`).
        self._receivers = itertools.count(1)
        #: The secure profile's stream authentication (fleet.transport.stream_auth): the
        #: digests of what this identity streams, and the samples it hears held until
        #: their author's digest vouches for them (a digest subscription per prefix).
        self._stream_signer: StreamSigner | None = None
        self._stream_checker: StreamChecker | None = None
        self._digests: dict[str, zenoh.Subscriber[None]] = {}
        #: The UAV whose stream a key is (None: not a stream); secure only, imported
        #: with the signing stack.
        self._stream_uav: Callable[[KeySpace, str], int | None] | None = None
        if signing is not None:
            from fleet.mission.signature import stream_uav
            from fleet.transport.stream_auth import StreamChecker, StreamSigner

            self._stream_signer = StreamSigner(self._put_digest)
            self._stream_checker = StreamChecker()
            self._stream_uav = stream_uav

    def _put_digest(self, key: str, digest: StreamDigest) -> None:
        self.put(key, bus_codec.encode(digest))

    def _watch_digests(self, key_expr: str) -> None:
        """Before the first subscription that may carry a UAV's streams under a prefix,
        hear the UAVs' signed digests there (a bus that hears no stream pays nothing)."""
        checker, space = self._stream_checker, space_of(key_expr)
        if checker is None or space is None:
            return
        from fleet.mission.signature import STREAM_KEYS

        wanted = zenoh.KeyExpr(key_expr)
        if not any(wanted.intersects(zenoh.KeyExpr(space.key(spec))) for spec in STREAM_KEYS):
            return

        def on_digest(received: BusSample) -> None:
            try:
                digest = bus_codec.decode(received.payload, StreamDigest, received.key)
            except bus_codec.BadMessage as error:
                log.warning("dropped a stream digest: %s", error)
                return
            checker.vouch(uav_identity(digest.uav), digest)

        self._hear_once(self._digests, space.prefix, space.all_digests, on_digest)

    def _watch_roster(self, key_expr: str) -> None:
        """In the secure profile, hear the roster on the prefix of `key_expr` (once per
        prefix, from the first key this bus uses there): a revocation put to the running
        fleet (`fleet certs revoke`) is applied at once, no restart needed."""
        signing = self.signing
        space = space_of(key_expr) if signing is not None else None
        if signing is None or space is None:
            return

        def on_roster(received: BusSample) -> None:
            signing.apply_roster(received.key, received.payload)

        self._hear_once(self._rosters, space.prefix, space.roster(), on_roster)

    def _hear_once(
        self,
        held: dict[str, zenoh.Subscriber[None]],
        prefix: str,
        key: str,
        on_put: Callable[[BusSample], None],
    ) -> None:
        """Subscribe `on_put` to `key` once for `prefix` (`held` keeps the subscriptions by
        prefix), every sample checked as a put to this bus is: dropped if refused."""
        with self._rosters_lock:
            if prefix in held:
                return

            receiver = self.new_receiver()

            def on_sample(sample: zenoh.Sample) -> None:
                received = self._received(sample, Delivery.PUT, receiver=receiver)
                if received is not None:
                    on_put(received)

            held[prefix] = self.session.declare_subscriber(key, direct(on_sample))

    @classmethod
    def open(cls, config: zenoh.Config) -> ZenohBus:
        """Open a session; raises zenoh.ZError if the config's router cannot be reached,
        CertError or RosterError if its identity's signing key or roster is unreadable."""
        return cls(zenoh.open(config), signing_of(config))

    @property
    def signed(self) -> bool:
        return self.signing is not None

    def new_receiver(self) -> int:
        """A new subscription's (or queryable's) own replay marks: each believes every
        signed message once, whichever other subscription of this bus heard it first."""
        return next(self._receivers)

    def _check(
        self, key: str, payload: bytes, attachment: bytes, how: Delivery, receiver: int = 0
    ) -> bool:
        return self.signing is None or self.signing.check(key, payload, attachment, how, receiver)

    def _received(
        self,
        sample: zenoh.Sample,
        how: Delivery,
        convert: Callable[[zenoh.Sample], BusSample] = _sample,
        receiver: int = 0,
    ) -> BusSample | None:
        """The sample (by `convert`), or None if its signature is refused at `receiver`."""
        bus_sample = convert(sample)
        attachment = _attachment(sample)
        if not self._check(bus_sample.key, bus_sample.payload, attachment, how, receiver):
            return None
        return bus_sample

    def put(self, key: str, payload: bytes) -> None:
        """Publish with the key's priority and congestion control (bus_qos).

        Telemetry goes through a publisher declared on its first put: a put on a declared
        publisher costs about half the CPU of a session put (the key is resolved once, not
        at each of the 20 puts a second), which counts in an idle onboard.
        """
        if self.signing is not None:
            attachment = self.signing.attachment(key, payload, Delivery.PUT)
            if attachment is not None:
                bus_qos.put(self.session, key, payload, attachment=attachment)
                return
            self._streamed(key, payload)
        publisher = self._publishers.get(key)
        if publisher is None:
            qos = bus_qos.qos_for(key)
            if qos is not bus_qos.TELEMETRY:
                bus_qos.put(self.session, key, payload, qos)
                return
            publisher = self._publishers.setdefault(key, bus_qos.declare(self.session, key, qos))
        publisher.put(payload)

    def _streamed(self, key: str, payload: bytes) -> None:
        """A sample put on one of this identity's own streams: in its next digest."""
        signer, space, stream_uav = self._stream_signer, space_of(key), self._stream_uav
        if signer is None or space is None or stream_uav is None or self.signing is None:
            return
        uav = stream_uav(space, key)
        if uav is None:
            return
        if uav_identity(uav) == self.signing.identity:
            signer.streamed(space.digest(uav), uav, key, payload)

    def subscribe(
        self, key_expr: str, callback: SampleCallback, *, details: bool = False
    ) -> Declaration:
        convert = _sample if details else _plain
        self._watch_roster(key_expr)
        self._watch_digests(key_expr)
        receiver = self.new_receiver()

        def on_sample(sample: zenoh.Sample) -> None:
            received = self._received(sample, Delivery.PUT, convert, receiver)
            if received is not None:
                self._believe(received, callback, receiver)

        subscriber: Declaration = self.session.declare_subscriber(key_expr, direct(on_sample))
        return subscriber

    def _believe(
        self, received: BusSample, deliver: Callable[[BusSample], None], receiver: int
    ) -> None:
        """`deliver` a sample whose signature (if any) passed at `receiver`: at once, or,
        a UAV's stream sample in the secure profile, once its signed digest lists it."""
        checker, stream_uav = self._stream_checker, self._stream_uav
        space = space_of(received.key) if stream_uav is not None else None
        uav = stream_uav(space, received.key) if stream_uav and space else None
        if checker is None or uav is None:
            deliver(received)
            return
        author = uav_identity(uav)
        checker.hold(author, received.key, received.payload, lambda: deliver(received), receiver)

    def subscribe_ring(self, key_expr: str, limit: int) -> RingSubscription:
        return _ZenohRing(self, key_expr, limit)

    def keep_latest(self, key_expr: str) -> Declaration | None:
        """Keep, unchecked, the latest signed message on each key under `key_expr`:
        checking each would cost a signature check per message (a state a second from
        every teammate); whoever it is relayed to checks it. A forgery kept instead of
        the real one (only a router can inject one) is refused there, as a message a
        router dropped would be missed."""
        signing = self.signing
        if signing is None:
            return None
        self._watch_roster(key_expr)

        def on_sample(sample: zenoh.Sample) -> None:
            attachment = _attachment(sample)
            if attachment:
                signing.keep(str(sample.key_expr), sample.payload.to_bytes(), attachment)

        subscriber: Declaration = self.session.declare_subscriber(key_expr, direct(on_sample))
        return subscriber

    def latest(self, key: str) -> bytes | None:
        return self.signing.latest(key) if self.signing is not None else None

    def get(
        self, selector: str, callback: SampleCallback, timeout: float, payload: bytes = b""
    ) -> None:
        self._watch_roster(selector)

        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                received = self._received(reply.ok, Delivery.REPLY)
                if received is not None:
                    callback(received)

        options = self._query_options(selector, payload)
        self.session.get(selector, direct(on_reply), timeout=timeout, **options)

    def _query_options(self, selector: str, payload: bytes) -> dict[str, Any]:
        """The payload of a query, signed when it is a command (`cmd/waypoint`, ...)."""
        if not payload:
            return {}
        options: dict[str, Any] = {"payload": payload}
        if self.signing is not None:
            attachment = self.signing.attachment(selector, payload, Delivery.QUERY)
            if attachment is not None:
                options["attachment"] = attachment
        return options

    def _accepted(self, reply: zenoh.Reply) -> bool:
        sample = reply.ok
        return sample is None or self._check(
            str(sample.key_expr), sample.payload.to_bytes(), _attachment(sample), Delivery.REPLY
        )

    def query(
        self, selector: str, timeout: float, payload: bytes = b"", *, every_reply: bool = False
    ) -> list[BusReply]:
        options: dict[str, Any] = (
            {"target": zenoh.QueryTarget.ALL, "consolidation": zenoh.ConsolidationMode.NONE}
            if every_reply
            else {}
        )
        self._watch_roster(selector)
        options.update(self._query_options(selector, payload))
        replies = self.session.get(selector, timeout=timeout, **options)
        if self.signing is None:
            return [_reply(reply) for reply in replies]
        answers: list[BusReply] = []
        for reply in replies:
            sample = reply.ok
            if sample is None:
                answers.append(_reply(reply))
                continue
            key, payload = str(sample.key_expr), sample.payload.to_bytes()
            accepted, author = self.signing.check_reply(key, payload, _attachment(sample))
            if accepted:
                answers.append(_reply(reply, author))
        return answers

    def declare_queryable(self, key_expr: str, notify: QueryNotify | None = None) -> Queryable:
        self._watch_roster(key_expr)
        return ZenohQueryable(self.session, key_expr, notify, self.signing, self.new_receiver())

    def declare_token(self, key: str) -> Declaration:
        token: Declaration = self.session.liveliness().declare_token(key)
        return token

    def live_tokens(self, key_expr: str, timeout: float) -> list[str]:
        replies = self.session.liveliness().get(key_expr, timeout=timeout)
        keys = [str(reply.ok.key_expr) for reply in replies if reply.ok is not None]
        return [key for key in keys if self._known_token(key)]

    def _known_token(self, key: str) -> bool:
        """In the secure profile, a liveliness token only of a UAV the roster names and
        has not revoked: a rogue router cannot make up an aircraft (a token carries no
        signature, so one of a real UAV cannot be told from a replayed one)."""
        signing, space = self.signing, space_of(key)
        if signing is None or space is None:
            return True
        parsed = space.parse(key)
        if parsed is None or parsed.uav is None or not parsed.uav.isdecimal():
            return True
        identity = uav_identity(int(parsed.uav))
        roster = signing.roster
        if identity in roster.keys and identity not in roster.revoked:
            return True
        from fleet.mission.signature import Refusal

        bus_codec.DROPPED.add(Refusal.UNKNOWN_AUTHOR)
        log.debug("ignored the liveliness token %s: %s is not a fleet identity", key, identity)
        return False

    def subscribe_presence(self, key_expr: str, callback: PresenceCallback) -> Declaration:
        self._watch_roster(key_expr)

        def on_token(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            if self._known_token(key):
                callback(key, sample.kind == zenoh.SampleKind.PUT)

        subscriber: Declaration = self.session.liveliness().declare_subscriber(
            key_expr, direct(on_token), history=True
        )
        return subscriber

    def close(self) -> None:
        if self._stream_signer is not None:
            self._stream_signer.flush()  # what was streamed last is vouched for too
            self._stream_signer.close()
        if not self.owns_session:
            for publisher in self._publishers.values():
                publisher.undeclare()
            self._publishers.clear()
            return
        self._publishers.clear()  # closing the session undeclares them
        self._close_session()

    def _close_session(self) -> None:
        # Also at exit (fleet.transport.zenoh_exit), if the bus was never closed.
        if not self.session.is_closed():
            self.session.close()


def session_of(bus: Bus) -> zenoh.Session:
    """The Zenoh session under `bus`, for what still speaks raw Zenoh (the recorder,
    the replayer); a FleetError if `bus` is not a Zenoh bus (the in-process one)."""
    from fleet.transport.bus_factory import unwrap

    opened = unwrap(bus)
    if not isinstance(opened, ZenohBus):
        raise BusConnectError(f"this command needs a Zenoh session, not {type(opened).__name__}")
    return opened.session


def signing_of(config: zenoh.Config) -> BusSigning | None:
    """The signing of a bus opened with `config`: the secure profile's (its identity's
    key, the roster), None in the open profile. The signing stack, and with it
    `cryptography`'s OpenSSL, is imported only for a config with a TLS identity, so an
    open-profile onboard never loads it (tests/onboard/test_import_footprint.py)."""
    if not has_tls_identity(config):
        return None
    from fleet.transport.signing import BusSigning

    return BusSigning.from_config(config)


def connect(target: ClientTarget, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S) -> ZenohBus:
    """A bus to the router at `target` (an endpoint, or a whole config).

    An endpoint gives a client session to it. Raises BusConnectError if none answers.
    """
    try:
        config = (
            make_config("client", [check_endpoint(target)]) if isinstance(target, str) else target
        )
    except ZenohConfigError as error:
        raise BusConnectError(str(error)) from None
    where = ", ".join(endpoints(config)) or "the configured endpoints"
    try:
        signing = signing_of(config)
    except (CertError, RosterError) as error:
        raise BusConnectError(f"cannot sign or check commands: {error}") from error
    config.insert_json5("transport/unicast/open_timeout", json.dumps(round(open_timeout_s * 1000)))
    try:
        session = zenoh.open(config)
    except zenoh.ZError as error:
        raise BusConnectError(
            f"no Zenoh router answers at {where} ({error_text(error)}). "
            f"Start one with `fleet up`, or point --connect / ${CONNECT_ENV} at it."
        ) from error
    log.debug("connected to %s as %s", where, session.zid())
    return ZenohBus(session, signing)


@contextmanager
def client_bus(
    target: ClientTarget, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S
) -> Iterator[ZenohBus]:
    """`connect` as a context manager: the bus is always closed."""
    bus = connect(target, open_timeout_s=open_timeout_s)
    try:
        yield bus
    finally:
        bus.close()
