"""Identities with one role each, attacked: real secure Zenoh routers on tls/ loopback
endpoints, real Zenoh clients with the fleet's identities. A router runs in this process
(`fleet.transport.router.Router`, what `python -m fleet.transport.router --secure` runs)
where the test asks only what it routes and refuses; as a process (marked `e2e`) where
the test reads what the router logs or `ground-cli` asks it.

* a rogue router presenting a UAV's certificate (which may not serve) is refused by the
  ground, and so is a router certificate dialled at a host it does not name;
* the router identity used as a client gets no rights at all, and a UAV's own router
  identity (router-per-UAV) no more than that UAV's;
* a session ends when the certificate at its other end expires.
"""

from __future__ import annotations

import datetime
import json
import logging
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest
import zenoh

from fleet.files.certs import write_identities
from fleet.files.signers import revoke
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.transport.bus_codec import ENCODING, encode
from fleet.transport.router import Router
from fleet.transport.secure import SecureProfile
from fleet.transport.zenoh_config import build_config, make_config
from tests.support import secure_clients
from tests.support.processes import Child, start_router
from tests.support.waiting import wait_until

SPACE = KeySpace()
NAMES = ["router", "ground", "uav-74", "uav-112", "router-74", "router-112"]
#: How long the short-lived identity of the expiry test lives.
SHORT_LIFE = datetime.timedelta(seconds=20)


@dataclass
class Certs:
    directory: Path

    def session(self, identity: str, endpoint: str) -> zenoh.Session:
        config = build_config(
            config_file=str(self.directory / f"{identity}.json5"), connect=[endpoint]
        )
        return zenoh.open(config)


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Certs:
    directory = tmp_path_factory.mktemp("certs")
    write_identities(directory, NAMES, [])
    return Certs(directory.resolve())


def router(
    certs: Certs, identity: str, host: str = "127.0.0.1", connect: tuple[str, ...] = ()
) -> tuple[Child, str]:
    return start_router(
        "--secure", str(certs.directory), "--identity", identity, "--listen", f"tls/{host}:0",
        *(argument for peer in connect for argument in ("--connect", peer)),
        name=f"router as {identity}",
    )  # fmt: skip


@contextmanager
def router_here(certs: Certs, identity: str, host: str = "127.0.0.1") -> Iterator[str]:
    """A secure router in this process presenting `identity`'s certificate: where it listens."""
    secure = SecureProfile.load(certs.directory, router_name=identity)
    with Router([f"tls/{host}:0"], secure=secure) as running:
        yield running.endpoints[0]


@pytest.fixture
def fleet_router(certs: Certs) -> Iterator[str]:
    """The fleet's router (identity `router`), in this process: one per test, so that
    none holds this process's refusal watch when a test counting refusals opens its own."""
    with router_here(certs, "router") as endpoint:
        yield endpoint


@pytest.fixture(scope="module")
def fleet_router_child(certs: Certs) -> Iterator[tuple[Child, str]]:
    child, endpoint = router(certs, "router")
    try:
        yield child, endpoint
    finally:
        child.stop()


class Heard:
    """What a session subscribed to `fleet/**` received, in order."""

    def __init__(self, session: zenoh.Session) -> None:
        self.samples: list[tuple[str, bytes]] = []
        self.lock = threading.Lock()
        self.subscriber = session.declare_subscriber("fleet/**", self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.samples.append((str(sample.key_expr), sample.payload.to_bytes()))

    def keys(self) -> list[str]:
        with self.lock:
            return [key for key, _ in self.samples]

    def last(self, key: str) -> bytes | None:
        with self.lock:
            values = [value for k, value in self.samples if k == key]
        return values[-1] if values else None


def mission(mission_id: int) -> bytes:
    return encode(MissionTargets(mission_id, (74, 112), (Target(42.36, -71.09, 100.0),)))


# ---- case 2: only a router's certificate may serve, for the hosts it names -----------------
@pytest.mark.parametrize("identity", ["uav-74", "ground"])
def test_a_rogue_router_with_a_client_certificate_is_refused(certs: Certs, identity: str) -> None:
    with router_here(certs, identity) as endpoint:
        for client in ("ground", "uav-112"):
            with pytest.raises(zenoh.ZError, match="Unable to connect"):
                certs.session(client, endpoint)


def test_a_router_certificate_for_another_host_is_refused(certs: Certs) -> None:
    # 127.0.0.2 reaches this host too, but no certificate names it.
    with (
        router_here(certs, "router", host="127.0.0.2") as endpoint,
        pytest.raises(zenoh.ZError, match="Unable to connect"),
    ):
        certs.session("ground", endpoint)


def test_the_real_router_is_accepted(certs: Certs, fleet_router: str) -> None:
    with certs.session("ground", fleet_router) as session:
        assert str(session.zid())


@pytest.mark.e2e
def test_a_refused_connection_is_in_the_routers_log(
    certs: Certs, fleet_router_child: tuple[Child, str]
) -> None:
    child, endpoint = fleet_router_child
    _refused_by(no_certificate(certs, endpoint))
    child.wait_for_line(lambda line: "WARN" in line and "certificate" in line, 10.0)


def trust_the_fleets_ca(certs: Certs, config: zenoh.Config) -> zenoh.Config:
    config.insert_json5(
        "transport/link/tls/root_ca_certificate", json.dumps(str(certs.directory / "ca.pem"))
    )
    return config


def no_certificate(certs: Certs, endpoint: str) -> zenoh.Config:
    """A client that trusts the fleet's CA but has no certificate of its own."""
    return trust_the_fleets_ca(certs, make_config("client", [endpoint]))


def expect_totals(certs: Certs, child: Child, endpoint: str, totals: str) -> None:
    """A client the router accepts counts nothing: `totals` are still its last word,
    logged as it stops (its output is read on, after the exit)."""
    with certs.session("ground", endpoint):
        pass
    child.stop()
    total = f"refused links in all: {totals}"
    wait_until(lambda: any(total in line for line in child.history[:]), 10.0, "the totals")


def _refused_by(config: zenoh.Config) -> None:
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(config)


class RouterLog:
    """What a router in this process logs (`caplog`): the same lines a router process
    writes to its log."""

    def __init__(self, caplog: pytest.LogCaptureFixture) -> None:
        caplog.set_level(logging.INFO)
        self.caplog = caplog

    def wait_for(self, text: str) -> None:
        def logged() -> bool:
            return any(text in record.getMessage() for record in self.caplog.records[:])

        wait_until(logged, 10.0, repr(text))


def expect_totals_here(
    certs: Certs, router_log: RouterLog, endpoint: str, stop: Callable[[], None], totals: str
) -> None:
    """`expect_totals` for a router in this process, stopped by `stop`."""
    with certs.session("ground", endpoint):
        pass
    stop()
    router_log.wait_for(f"refused links in all: {totals}")


# A test counting refusals opens its router in its body: they are read from Zenoh's log
# on this process's standard output (`fleet.transport.refusal_watch`), which pytest's
# capture takes back between a fixture's setup and the test's call.
def test_refused_connections_are_counted_by_kind(
    certs: Certs, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    router_log = RouterLog(caplog)
    foreign = tmp_path / "foreign"
    write_identities(foreign, ["uav-74"], [])
    with ExitStack() as running:  # its own, alone in this process: the counts start at zero
        endpoint = running.enter_context(router_here(certs, "router"))
        _refused_by(no_certificate(certs, endpoint))
        router_log.wait_for("refused links so far: no_certificate=1")
        # A certificate of another CA, presented to a client that trusts the fleet's CA.
        other_ca = build_config(config_file=str(foreign / "uav-74.json5"), connect=[endpoint])
        trust_the_fleets_ca(certs, other_ca)
        _refused_by(other_ca)
        router_log.wait_for("refused links so far: no_certificate=1 unknown_ca=1")
        _refused_by(no_certificate(certs, endpoint))
        # A client of the other CA altogether refuses the router's certificate itself.
        _refused_by(build_config(config_file=str(foreign / "uav-74.json5"), connect=[endpoint]))
        router_log.wait_for("refused links so far: no_certificate=2 unknown_ca=1 peer_refused=1")
        expect_totals_here(
            certs,
            router_log,
            endpoint,
            running.close,
            "no_certificate=2 unknown_ca=1 peer_refused=1",
        )


def test_a_revoked_identitys_session_is_counted(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    router_log = RouterLog(caplog)
    write_identities(tmp_path, ["router", "ground", "uav-300"], [])
    revoke(tmp_path, ["uav-300"])
    certs = Certs(tmp_path.resolve())
    with ExitStack() as running:
        endpoint = running.enter_context(router_here(certs, "router"))
        with certs.session("uav-300", endpoint):  # TLS lets it in; the ACL grants nothing
            router_log.wait_for("refused links so far: no_rights=1")
        expect_totals_here(certs, router_log, endpoint, running.close, "no_rights=1")


@pytest.mark.e2e
def test_ground_cli_routers_shows_each_router_of_a_mesh(certs: Certs) -> None:
    ground_router, endpoint = router(certs, "router")
    uav_router, uav_endpoint = router(certs, "router-74", connect=(endpoint,))
    try:
        _refused_by(no_certificate(certs, uav_endpoint))
        uav_router.wait_for_line(lambda line: "refused links so far: no_certificate=1" in line, 10)

        def routers() -> list[dict[str, object]]:
            answer = secure_clients.ground_cli(certs.directory, endpoint, "routers", "--json")
            assert answer.returncode == 0, answer.stderr
            found: list[dict[str, object]] = json.loads(answer.stdout)
            return found

        # The ground, on its own router, hears UAV 74's router too (the mesh forms in
        # the background: asked until both answer).
        wait_until(lambda: len(routers()) == 2, 30.0, "both routers answering")
        assert sorted(json.dumps(r["refused_links"]) for r in routers()) == [
            '{"no_certificate": 1}',
            "{}",
        ]
    finally:
        uav_router.stop()
        ground_router.stop()


# ---- case 3: the router identities used as clients ------------------------------------------
def test_the_router_identity_as_a_client_commands_nothing(certs: Certs, fleet_router: str) -> None:
    with (
        certs.session("ground", fleet_router) as ground,
        certs.session("uav-74", fleet_router) as uav74,
    ):
        heard_by_uav = Heard(uav74)
        with certs.session("router", fleet_router) as rogue:
            rogue.put(SPACE.mission_targets(900), mission(900), encoding=ENCODING)
            rogue.put(SPACE.mission_abort(900), b"{}", encoding=ENCODING)
            rogue.put(SPACE.status(74), b"forged", encoding=ENCODING)
            # Closing sends what it holds first: the router has read the forged puts
            # before the ground's mission below is sent.
        with certs.session("router", fleet_router) as rogue:
            heard_by_rogue = Heard(rogue)
            ground.put(SPACE.mission_targets(901), mission(901), encoding=ENCODING)
            wait_until(
                lambda: SPACE.mission_targets(901) in heard_by_uav.keys()[:], 10.0, "mission 901"
            )
            ground.put(SPACE.mission_targets(902), mission(902), encoding=ENCODING)
            wait_until(
                lambda: SPACE.mission_targets(902) in heard_by_uav.keys()[:], 10.0, "mission 902"
            )
            # Nothing the rogue said reached UAV 74, and it may not even listen.
            assert heard_by_uav.keys() == [SPACE.mission_targets(901), SPACE.mission_targets(902)]
            assert heard_by_rogue.keys() == []


def test_a_uavs_router_identity_has_that_uavs_rights_only(certs: Certs, fleet_router: str) -> None:
    with (
        certs.session("uav-112", fleet_router) as uav112,
        certs.session("router-74", fleet_router) as rogue,
    ):
        heard = Heard(uav112)

        def delivered(marker: bytes) -> bool:
            # A status as UAV 74 (its right), put again until heard: the router may not
            # know 112's subscription at first.
            rogue.put(SPACE.status(74), marker, encoding=ENCODING)
            return heard.last(SPACE.status(74)) == marker

        wait_until(lambda: delivered(b"ready"), 30.0, "a first status of UAV 74 delivered")
        rogue.put(SPACE.mission_targets(903), mission(903), encoding=ENCODING)
        rogue.put(SPACE.opm(112), b"false", encoding=ENCODING)
        rogue.put(SPACE.status(112), b"forged", encoding=ENCODING)
        # After the forgeries on the same session: what 112 heard by then is all it gets.
        wait_until(lambda: delivered(b"marker"), 30.0, "the marker")
        assert set(heard.keys()) == {SPACE.status(74)}  # the forgeries: none heard


# ---- case 6: a session ends with its certificate --------------------------------------------
@pytest.mark.e2e
def test_a_session_ends_when_its_certificate_expires(tmp_path: Path) -> None:
    expiry = datetime.datetime.now(datetime.UTC) + SHORT_LIFE
    write_identities(
        tmp_path, ["router", "ground", "uav-112"], [], lifetime={"uav-112": SHORT_LIFE}
    )
    certs = Certs(tmp_path.resolve())
    child, endpoint = router(certs, "router")
    with (
        certs.session("ground", endpoint) as ground,
        certs.session("uav-112", endpoint) as short,
    ):
        heard = Heard(ground)
        stop = threading.Event()

        def publish() -> None:
            count = 0
            while not stop.wait(0.2):  # bounded by stop, set below whatever happens
                count += 1
                short.put(SPACE.status(112), str(count).encode())

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            wait_until(lambda: heard.last(SPACE.status(112)) is not None, 10.0, "a first status")
            # Past expiry, the statuses stop: the link closed and cannot reopen.
            wait_until(lambda: datetime.datetime.now(datetime.UTC) > expiry, 60.0, "the expiry")

            def stalled() -> bool:
                before = heard.last(SPACE.status(112))
                time.sleep(2.0)  # five publications: none may arrive
                return heard.last(SPACE.status(112)) == before

            wait_until(stalled, 60.0, "statuses to stop after the certificate expired")
            assert publisher.is_alive()  # still publishing: the router no longer hears it
        finally:
            stop.set()
            publisher.join(5)
            child.stop()
