"""No lie survives a hop: a claim about an aircraft is believed only from that aircraft's
own signed message. A secure fleet of real processes (router with mutual TLS and access
control, the simulator, onboards 74 and 112, `ground-cli`) attacked by a captured UAV 74
(its certificate and signing key), a captured UAV router (`router-74`), a revoked
identity and a replay across an onboard's restart.

Each refusal is observed, not assumed: the attacked UAV counts what it refused in its
state's link drops, or a later message of the attacker's, sent in order after the lie,
is seen handled first.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh

from fleet.files.certs import IdentityFiles, tls_settings
from fleet.geo.aircraft import AircraftLimits
from fleet.mission.messages import (
    RouterState,
    StatusText,
    TargetOutcome,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.mission.target_checks import REACHED_RADIUS_M
from fleet.mission.targets_file import decode_targets
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.transport.bus_codec import ENCODING, encode
from fleet.transport.router import bound_endpoints
from fleet.transport.zenoh_config import make_config
from tests.support import signed
from tests.support.ground_cli import ground_cli
from tests.support.secure_fleet import SPACE, TARGETS_FILE, SignedFleet, signed_fleet
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

#: uav-299 is in the roster, never flown: its key is the fleet's, its token anyone's.
IDENTITIES = ["router", "router-74", "ground", "uav-74", "uav-112", "uav-299", "uav-300"]
#: Slow enough that 112 is minutes from its target when it is lied about.
SPEEDUP = 2.0
MAX_AIRSPEED_M_S = AircraftLimits().max_airspeed
TARGETS = decode_targets(Path(TARGETS_FILE).read_bytes(), TARGETS_FILE)


@pytest.fixture(scope="module")
def secure(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SignedFleet]:
    certs = tmp_path_factory.mktemp("certs").resolve()
    with signed_fleet(certs, IDENTITIES, speedup=SPEEDUP) as fleet:
        yield fleet


def distance_m(state: UavState, target: tuple[float, float]) -> float:
    """Roughly how far `state`'s aircraft is from `target` (an equirectangular estimate)."""
    assert state.telemetry is not None and state.telemetry.gps is not None
    lat, lon = state.telemetry.gps.lat, state.telemetry.gps.lon
    north = math.radians(target[0] - lat) * 6_371_000.0
    east = math.radians(target[1] - lon) * 6_371_000.0 * math.cos(math.radians(lat))
    return math.hypot(north, east)


# ---- a captured aircraft lies about its teammate ----------------------------------------------
class Reach:
    """Whether an aircraft *could* have reached a spot since it was seen `away` metres
    from it: no faster than the simulated airframe's top speed, sped up."""

    def __init__(self, away: float) -> None:
        self.away, self.since = away, time.monotonic()

    def possible(self) -> bool:
        flown = (time.monotonic() - self.since) * MAX_AIRSPEED_M_S * SPEEDUP
        return self.away - flown <= REACHED_RADIUS_M


def test_a_captured_uav_cannot_mark_its_teammates_target_reached(secure: SignedFleet) -> None:
    """UAV 74's own, correctly signed outcome lists 112's target as reached by 112, put
    live and served to the ground. 112 does not take it (nor re-sign it) and flies on,
    and `ground-cli mission` does not show it reached."""
    mission = secure.send_targets()

    def committed() -> bool:
        state = secure.state(112)
        return bool(state and state.mission and state.mission.assignment and state.telemetry)

    wait_until(committed, 60.0, "112 committed")
    state = secure.state(112)
    assert state is not None and state.mission is not None
    report = state.mission.assignment
    assert report is not None
    queue = report.queues.get(112) or (report.pairs[112],)
    target = queue[-1]  # the one 112 reaches last: the furthest off
    where = TARGETS[target]
    spot = (where.lat, where.lon)
    reach = Reach(distance_m(state, spot))
    assert not reach.possible(), "112 is already at its target"

    key = SPACE.mission_outcome(mission, 74)
    lie = encode(TargetOutcome(mission, 74, None, Phase.REACHED, reached={target: 112}))

    def serve(query: zenoh.Query) -> None:
        if query.key_expr.intersects(zenoh.KeyExpr(key)):
            by_74 = signed.attachment(secure.certs, "uav-74", key, lie)
            query.reply(key, lie, encoding=ENCODING, attachment=by_74)

    with secure.session("uav-74") as attacker:
        queryable = attacker.declare_queryable(SPACE.mission_outcomes(mission), serve)
        before = secure.refused(112, "unsigned")

        def lied() -> bool:
            # Put until seen: the lie, then an unsigned message after it on the same
            # session, which 112 refuses and counts once the lie has been handled.
            by_74 = signed.attachment(secure.certs, "uav-74", key, lie)
            attacker.put(key, lie, encoding=ENCODING, attachment=by_74)
            attacker.put(key, lie, encoding=ENCODING)
            return secure.refused(112, "unsigned") > before

        wait_until(lied, 30.0, "112 handling 74's outcome")
        after = secure.state(112)
        assert after is not None and after.mission is not None
        assert after.mission.reached.get(target) != 112 or reach.possible(), (
            f"112 took 74's word that it reached target {target}"
        )
        shown = secure.ground_cli("mission", "--mission", str(mission), "--json")
        queryable.undeclare()
    assert shown.returncode in (0, 1), shown.stderr[-3000:]
    states = {s["index"]: s for s in json.loads(shown.stdout)["target_states"]}
    assert states[target]["state"] != "reached" or reach.possible(), (
        f"the ground shows target {target} reached by {states[target]['uav']} on 74's word"
    )


# ---- a captured UAV router speaks for another router ------------------------------------------
def routers(secure: SignedFleet) -> list[dict[str, Any]]:
    answer = secure.ground_cli("routers", "--json")
    assert answer.returncode == 0, answer.stderr[-3000:]
    found: list[dict[str, Any]] = json.loads(answer.stdout)
    return found


def test_a_uav_routers_key_cannot_answer_for_another_router(secure: SignedFleet) -> None:
    """`router-74`'s key answers `router/state` with the fleet router's zid and no refused
    link, after the real one. The ground shows the real router's count as its own, and
    the forgery as `router-74`'s word."""
    (real,) = routers(secure)
    no_certificate = make_config("client", [secure.endpoint])
    ca = json.dumps(str(secure.certs / "ca.pem"))
    no_certificate.insert_json5("transport/link/tls/root_ca_certificate", ca)
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(no_certificate)
    refused = real["refused_links"].get("no_certificate", 0) + 1
    wait_until(
        lambda: routers(secure)[0]["refused_links"].get("no_certificate", 0) >= refused,
        30.0,
        "the router counting the refused link",
    )
    key = SPACE.router_state()
    lie = encode(RouterState(real["zid"], {}))

    def answer_late(query: zenoh.Query) -> None:
        time.sleep(0.5)  # after the real router's answer: the later one used to win
        by_router_74 = signed.attachment(secure.certs, "router-74", key, lie)
        query.reply(key, lie, encoding=ENCODING, attachment=by_router_74)

    with secure.session("router-74") as rogue:
        queryable = rogue.declare_queryable(key, answer_late)
        shown = routers(secure)
        queryable.undeclare()
    for entry in shown:
        if entry["zid"] == real["zid"] and not entry["refused_links"]:
            assert entry.get("identity") == "router-74", f"the forgery shown as {entry}"
    assert any(
        e.get("identity") == "router" and e["refused_links"].get("no_certificate", 0) >= refused
        for e in shown
    ), shown


# ---- revocation reaches running processes -----------------------------------------------------
class Heard:
    """Samples a raw session heard on a key, with when (thread-safe: Zenoh calls in)."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self._lock = threading.Lock()
        self.samples: list[tuple[float, bytes]] = []
        self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self.samples.append((time.monotonic(), sample.payload.to_bytes()))

    def since(self, moment: float) -> list[bytes]:
        with self._lock:
            return [payload for at, payload in self.samples if at > moment]

    def close(self) -> None:
        self._subscriber.undeclare()


def test_a_revoked_identitys_open_session_is_closed_by_the_router_within_seconds(
    secure: SignedFleet,
) -> None:
    """UAV 300's session is open and what it puts reaches the ground. `fleet certs
    revoke` on the running fleet: the router closes that session within seconds, with no
    restart; 300 dials again at once and the router closes the new link before routing a
    byte of it (what 300 puts meanwhile never reaches the ground), while 74 and 112 fly
    on and keep reporting, and `ground-cli routers` counts the links it closed."""
    key = SPACE.telemetry(300)
    heard = Heard(secure.ground, key)
    honest = {uav: Heard(secure.ground, SPACE.telemetry(uav)) for uav in (74, 112)}
    #: 300's transport opening (PUT) and closing (DELETE), with how many puts it had made.
    events: list[tuple[zenoh.SampleKind, int]] = []
    sent = 0
    try:
        with secure.session("uav-300") as lost:
            lost.info.declare_transport_events_listener(
                lambda event: events.append((event.kind, sent)), history=True
            )

            def put() -> None:
                nonlocal sent
                sent += 1
                lost.put(key, str(sent).encode())

            def reached() -> bool:
                put()
                return bool(heard.since(0.0))

            wait_until(reached, 30.0, "what the open session puts reaching the ground")
            revoked = subprocess.run(
                [sys.executable, "-m", "programs.fleet_cli", "certs", "revoke",
                 str(secure.certs), "uav-300", "--connect", secure.endpoint],
                capture_output=True, text=True, timeout=120, check=False,
            )  # fmt: skip
            assert revoked.returncode == 0, revoked.stderr[-3000:]
            assert f"put on {SPACE.roster()}" in revoked.stdout, revoked.stdout
            since = time.monotonic()

            def closes() -> list[int]:
                return [n for kind, n in events if kind == zenoh.SampleKind.DELETE]

            def closed(times: int) -> bool:
                put()  # on the open link while there is one
                return len(closes()) >= times

            wait_until(lambda: closed(1), 30.0, "the router closing 300's session")
            # 300 dials again (a transport opens on its side, and it puts on it) and the
            # router closes that link too: its reconnection is refused.
            wait_until(lambda: closed(2), 60.0, "the router closing 300's reconnection")
        first_close, second_close = closes()[:2]
        reopened = [n for kind, n in events if kind == zenoh.SampleKind.PUT and n >= first_close]
        assert reopened and second_close > reopened[0], f"no put on the reconnection: {events}"
        # Everything 300 put is past the ground by now: fresh telemetry of both honest
        # UAVs, put after 300's last, arrived through the same router.
        last_put = time.monotonic()
        for uav, samples in honest.items():
            wait_until(lambda s=samples: s.since(last_put), 30.0, f"{uav}'s telemetry after")
        late = [n for n in map(int, heard.since(0.0)) if n > first_close]
        assert not late, f"300's puts after its session was closed reached the ground: {late}"
        for uav, samples in honest.items():
            assert samples.since(since), f"{uav} stopped reporting after the revocation"
        routers = secure.ground_cli("routers")
        assert routers.returncode == 0, routers.stderr[-3000:]
        counted = re.search(r"revoked=(\d+)", routers.stdout)
        assert counted and int(counted[1]) >= 2, routers.stdout
    finally:
        heard.close()
        for samples in honest.values():
            samples.close()


# ---- a captured UAV router as the ground's router ---------------------------------------------
def test_a_rogue_router_cannot_invent_an_aircraft_a_position_or_a_status(
    secure: SignedFleet,
) -> None:
    """A router holding `router-74`'s key, meshed with the fleet's router, is the one the
    ground connects to (a UAV router as a fallback). It puts UAV 112 at 10 N 10 E, an
    "engine fire" status from 112, and a ghost UAV 299 (telemetry and a liveliness token;
    299 is in the roster, so the token is of a fleet identity, but the rogue has no
    key of 299's). `ground-cli watch` shows the real 74 and 112, where they are, and none
    of it; `ground-cli uavs` lists 74 and 112 only."""
    config = make_config("router", [secure.endpoint], ["tls/127.0.0.1:0"])
    tls = tls_settings(IdentityFiles(secure.certs, "router-74"))
    config.insert_json5("transport/link/tls", json.dumps(tls))
    nowhere = Telemetry(1000, gps=GpsBlock(10.0, 10.0, 600.0, 0.0, 0.0, 0.0))
    fire = StatusText("engine fire", StatusKind.ERROR)
    with zenoh.open(config) as rogue:
        (rogue_endpoint,) = bound_endpoints(rogue, ["tls/127.0.0.1:0"])
        token = rogue.liveliness().declare_token(SPACE.alive(299))
        stop = threading.Event()

        def inject() -> None:
            while not stop.wait(0.1):
                rogue.put(SPACE.telemetry(112), encode(nowhere), encoding=ENCODING)
                rogue.put(SPACE.telemetry(299), encode(nowhere), encoding=ENCODING)
                rogue.put(SPACE.status(112), encode(fire), encoding=ENCODING)

        injector = threading.Thread(target=inject, daemon=True)
        injector.start()
        try:
            shown = ground_cli(
                "--zenoh-config", str(secure.certs / "ground.json5"), "watch", "--duration", "6",
                connect=rogue_endpoint, timeout=120,
            )  # fmt: skip
            listed = ground_cli(
                "--zenoh-config", str(secure.certs / "ground.json5"), "uavs", "--json",
                connect=rogue_endpoint, timeout=120,
            )  # fmt: skip
        finally:
            stop.set()
            injector.join(5.0)
            token.undeclare()
    assert shown.returncode == 0, shown.stderr[-3000:]
    assert listed.returncode == 0, listed.stderr[-3000:]
    assert sorted(view["id"] for view in json.loads(listed.stdout)) == [74, 112], listed.stdout
    rows = {line.split()[0]: line.split() for line in shown.stdout.splitlines() if line.strip()}
    assert "engine fire" not in shown.stdout, shown.stdout[-2000:]
    assert "299" not in rows, shown.stdout[-2000:]
    assert "112" in rows and "74" in rows, shown.stdout[-2000:]
    # The real telemetry, vouched for by 112's signed digests, is shown; the forged is not.
    shown_at = [
        float(cells[1])
        for cells in map(str.split, shown.stdout.splitlines())
        if cells and cells[0] == "112" and cells[1] != "-"
    ]
    assert shown_at, shown.stdout[-2000:]
    assert all(abs(lat - 35.7) < 0.5 for lat in shown_at), f"112 shown at {shown_at}"


def test_a_captured_uavs_re_plan_cannot_release_its_teammate(secure: SignedFleet) -> None:
    """UAV 74's own, correctly signed re-plan (epoch + 1) says 112 dropped out. That is a
    claim about 112, which flies on: 112 does not release itself on 74's word."""
    mission = secure.send_targets()

    def committed() -> bool:
        state = secure.state(112)
        return bool(state and state.mission and state.mission.assignment)

    wait_until(committed, 60.0, "112 committed")
    state = secure.state(112)
    assert state is not None and state.mission is not None
    report = state.mission.assignment
    assert report is not None
    forged = msgspec.structs.replace(
        report, uav=74, target=report.pairs.get(74), epoch=report.epoch + 1, released=(112,)
    )
    key, lie = SPACE.mission_replan(mission, 74), encode(forged)
    with secure.session("uav-74") as attacker:
        before = secure.refused(112, "unsigned")

        def lied() -> bool:
            by_74 = signed.attachment(secure.certs, "uav-74", key, lie)
            attacker.put(key, lie, encoding=ENCODING, attachment=by_74)
            attacker.put(key, lie, encoding=ENCODING)  # after it: counted once it is handled
            return secure.refused(112, "unsigned") > before

        wait_until(lied, 30.0, "112 handling 74's re-plan")
    after = secure.state(112)
    assert after is not None and after.mission is not None
    held = after.mission.assignment
    assert held is not None and 112 not in held.released, f"112 released on 74's word: {held}"
