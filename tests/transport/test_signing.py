"""Signed commands on real Zenoh sessions (a router on loopback, in this process): what
a `ZenohBus` with `BusSigning` signs, relays and refuses."""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from fleet.files.certs import write_identities
from fleet.files.signers import (
    load_signing_key,
    revoke,
    roster_document,
    signing_key_path,
)
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionAbort, MissionTargets, Target, UavState
from fleet.mission.signature import Delivery, sign
from fleet.transport import bus_codec
from fleet.transport.bus import BusQuery, Queryable
from fleet.transport.bus_codec import encode
from fleet.transport.signing import RELAY_CACHE, BusSigning
from fleet.transport.zenoh_bus import ZenohBus, client_bus, connect
from fleet.transport.zenoh_config import build_config
from tests.support.heard import Heard
from tests.support.signed import bus_signing, buses_of
from tests.support.waiting import wait_until

SPACE = KeySpace()
TIMEOUT_S = 2.0
TARGETS = MissionTargets(5, (74, 112), (Target(35.7, -120.7, 600.0),))


def signed_bus(certs: Path, endpoint: str, identity: str) -> ZenohBus:
    """A client of the router at `endpoint` that signs and checks commands as `identity`
    (signing set after it opened: no stream checks)."""
    bus = connect(endpoint)
    bus.signing = bus_signing(certs, identity)
    return bus


@pytest.fixture
def buses(certs: Path, endpoint: str) -> Iterator[dict[str, ZenohBus]]:
    with buses_of(
        ("ground", "uav-74", "uav-112"), lambda name: signed_bus(certs, endpoint, name)
    ) as made:
        yield made


@contextmanager
def serving(bus: ZenohBus, key_expr: str, answer: Callable[[BusQuery], None]) -> Iterator[None]:
    """Queries on `key_expr` answered by `answer` as they arrive (on the bus's thread)."""
    holder: list[Queryable] = []

    def on_query() -> None:
        while holder and (query := holder[0].try_recv()) is not None:
            answer(query)
            query.drop()

    holder.append(bus.declare_queryable(key_expr, on_query))
    on_query()  # any that arrived before the queryable was kept
    try:
        yield
    finally:
        holder[0].undeclare()


def refused(reason: str) -> int:
    return bus_codec.DROPPED.counts().get(reason, 0)


def test_the_grounds_mission_is_heard_and_an_unsigned_one_is_refused(
    buses: dict[str, ZenohBus], endpoint: str
) -> None:
    heard = Heard()
    subscription = buses["uav-112"].subscribe(SPACE.all_mission_targets, heard)
    ground = buses["ground"]
    # Until the subscription has reached the router, a put may go unheard.

    def published_and_heard() -> bool:
        ground.publish(SPACE.mission_targets(5), TARGETS)
        return bool(heard.samples)

    wait_until(published_and_heard, 5.0, "the subscription in place")
    before = refused("unsigned")
    with client_bus(endpoint) as rogue:  # no signing: puts the bytes as they are
        rogue.publish(SPACE.mission_targets(6), TARGETS)
        rogue.publish(SPACE.mission_targets(7), TARGETS)
    wait_until(lambda: refused("unsigned") == before + 2, 5.0, "the rogue's refused")
    ground.publish(SPACE.mission_targets(8), TARGETS)
    wait_until(lambda: SPACE.mission_targets(8) in {s.key for s in heard.samples}, 5.0)
    subscription.undeclare()
    assert {s.key for s in heard.samples} == {SPACE.mission_targets(5), SPACE.mission_targets(8)}


def test_a_uav_relays_the_grounds_mission_and_cannot_serve_its_own(
    buses: dict[str, ZenohBus],
) -> None:
    """On the bus: a teammate catching up believes the ground's mission
    whoever relays it, and no mission a UAV made up."""
    heard = Heard()
    subscription = buses["uav-74"].subscribe(SPACE.all_mission_targets, heard)

    def heard_the_mission() -> bool:
        # Put again until heard: the router may not know the subscription yet.
        buses["ground"].publish(SPACE.mission_targets(7), TARGETS)
        return heard.arrived.wait(0.2)

    wait_until(heard_the_mission, TIMEOUT_S * 5, "UAV 74 heard the ground's mission")
    subscription.undeclare()
    forged = MissionTargets(4_000_000_000, (112,), (Target(35.75, -120.8, 600.0),))

    def answer(query: BusQuery) -> None:
        query.reply(SPACE.mission_targets(7), TARGETS)  # re-encoded, relayed as signed
        query.reply(SPACE.mission_targets(4_000_000_000), forged)  # 74's own making
        query.reply(SPACE.mission_abort(7), MissionAbort(7))  # never signed by the ground

    before = refused("unsigned") + refused("not_entitled")
    replies: list[Any] = []

    def relayed() -> bool:
        # Ask again until the router knows the queryable (before, no reply at all).
        replies[:] = buses["uav-112"].query(SPACE.all_mission_keys, TIMEOUT_S)
        return bool(replies)

    with serving(buses["uav-74"], SPACE.all_mission_keys, answer):
        wait_until(relayed, TIMEOUT_S * 5, "UAV 74's answer")
    assert [(r.key, r.ok) for r in replies] == [(SPACE.mission_targets(7), True)]
    assert refused("unsigned") + refused("not_entitled") == before + 2


def test_an_autopilot_command_is_obeyed_only_from_the_ground(
    buses: dict[str, ZenohBus],
) -> None:
    answered: list[str] = []

    def answer(query: BusQuery) -> None:
        answered.append(query.payload.decode())
        query.reply_bytes(SPACE.command(112, "track"), b'{"ok": true, "detail": ""}')

    from_ground: list[Any] = []

    def ground_answered() -> bool:
        from_ground[:] = buses["ground"].query(
            SPACE.command(112, "track"), TIMEOUT_S, b'{"waypoint": 90}'
        )
        return bool(from_ground)

    with serving(buses["uav-112"], SPACE.command(112, "*"), answer):
        # The ground's query first, until the queryable's declaration has reached the
        # router (a query before it gets no reply at all, refused or not).
        wait_until(ground_answered, 10.0, "the ground's command answered")
        from_74 = buses["uav-74"].query(SPACE.command(112, "track"), TIMEOUT_S, b'{"waypoint": 50}')
    assert [r.ok for r in from_74] == [False]
    assert b"refused" in from_74[0].payload
    assert [r.ok for r in from_ground] == [True]  # the UAV's signed answer, believed
    assert answered == ['{"waypoint": 90}']


def test_a_config_of_the_secure_profile_signs_and_others_do_not(certs: Path) -> None:
    config = build_config(config_file=str(certs / "uav-74.json5"))
    signing = BusSigning.from_config(config)
    assert signing is not None and signing.identity == "uav-74"
    assert BusSigning.from_config(zenoh.Config()) is None
    (certs / "uav-74.sign").rename(certs / "moved")
    try:
        with pytest.raises(Exception, match=r"uav-74\.sign: not a readable signing key"):
            BusSigning.from_config(config)
    finally:
        (certs / "moved").rename(certs / "uav-74.sign")


def test_a_reply_passes_on_the_message_as_first_signed(certs: Path) -> None:
    """The ground serving its mission while it flies, and a UAV relaying it, both pass on
    the put's own envelope: its time is when the mission was sent, not when asked."""
    now = [1_000]
    ground = bus_signing(certs, "ground", clock=lambda: now[0])
    uav = bus_signing(certs, "uav-74", clock=lambda: now[0])
    key, payload = SPACE.mission_targets(9), encode(TARGETS)
    put = ground.attachment(key, payload, Delivery.PUT)
    assert put is not None and uav.check(key, payload, put, Delivery.PUT)
    now[0] += 60 * 1_000_000_000
    assert ground.reply(key, payload) == (payload, put)
    assert uav.reply(key, payload) == (payload, put)
    # Other content on the key: signed afresh by its author, never relayed as the ground's.
    other = encode(MissionTargets(9, (74,), TARGETS.targets))
    fresh = ground.reply(key, other)
    assert fresh[0] == other and fresh[1] not in (None, put)
    assert uav.reply(SPACE.mission_targets(10), payload) == (payload, None)


def test_a_relay_passes_on_the_envelope_of_the_very_mission_it_holds(certs: Path) -> None:
    """Two grounds (one identity) sent two missions under one id: a UAV holding the
    first still relays it with its own envelope after hearing the second, and never
    hands over either envelope with other content."""
    now = [1_000]

    def signing(identity: str) -> BusSigning:
        return bus_signing(certs, identity, clock=lambda: now[0])

    first_ground, second_ground, uav = signing("ground"), signing("ground"), signing("uav-74")
    key = SPACE.mission_targets(9)
    held, rival = encode(TARGETS), encode(MissionTargets(9, (74,), TARGETS.targets))
    held_put = first_ground.attachment(key, held, Delivery.PUT)
    assert held_put is not None and uav.check(key, held, held_put, Delivery.PUT)
    now[0] += 1_000_000
    rival_put = second_ground.attachment(key, rival, Delivery.PUT)
    assert rival_put is not None and uav.check(key, rival, rival_put, Delivery.PUT)
    assert uav.reply(key, held) == (held, held_put)
    assert uav.reply(key, rival) == (rival, rival_put)
    made_up = encode(MissionTargets(9, (74, 112), ()))
    assert uav.reply(key, made_up) == (made_up, None)
    # However many messages later on other keys and this one, the held one stays relayable
    # while it is relayed.
    for mission in range(10, 10 + 2 * RELAY_CACHE):
        now[0] += 1_000_000
        other = SPACE.mission_targets(mission)
        put = first_ground.attachment(other, held, Delivery.PUT)
        assert put is not None and uav.check(other, held, put, Delivery.PUT)
        if mission % 100 == 0:
            assert uav.reply(key, held) == (held, held_put)
    assert uav.reply(key, held) == (held, held_put)


def test_a_state_reply_signed_longer_ago_than_the_replay_window_is_refused_and_said(
    buses: dict[str, ZenohBus], certs: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """UAV 112's genuine signed state, 31 s old (recorded, replayed as the answer to a
    late-joining ground's state query) is refused as stale, counted, and logged with its
    age; the same state signed now is believed. On the code before, the old one was
    believed: a reply was not judged for its age."""
    key = SPACE.state(112)
    payload = encode(UavState(112, True, 1.0, None, None, None, None))
    signing_key = load_signing_key(signing_key_path(certs, "uav-112"))
    age_ns = [31 * 1_000_000_000]

    def answer(query: zenoh.Query) -> None:
        stamp = time.time_ns() - age_ns[0]
        by_112 = sign(signing_key, "uav-112", key, payload, stamp)
        query.reply(key, payload, encoding=bus_codec.ENCODING, attachment=by_112)

    queryable = buses["uav-112"].session.declare_queryable(key, answer)
    try:
        fresh: list[Any] = []
        before = refused("stale")

        def asked_and_refused() -> bool:
            # Ask until the router knows the queryable and the answer is refused.
            fresh[:] = buses["ground"].query_messages(key, UavState, TIMEOUT_S)
            return refused("stale") > before

        with caplog.at_level(logging.WARNING, logger="fleet.transport.signing"):
            wait_until(asked_and_refused, TIMEOUT_S * 5, "the old state refused")
        assert fresh == []
        assert any(
            f"refused a reply on {key} signed by uav-112 31." in record.message
            and "older than the 30 s replay window" in record.message
            for record in caplog.records
        ), caplog.text
        age_ns[0] = 0
        believed = buses["ground"].query_messages(key, UavState, TIMEOUT_S)
    finally:
        queryable.undeclare()
    assert [(k, state.uav) for k, state in believed] == [(key, 112)]


# ---- the roster, live ----------------------------------------------------------------------------
def test_a_roster_put_by_the_ground_revokes_at_once_and_never_revives(
    tmp_path: Path, endpoint: str
) -> None:
    """A revocation put on `roster` (CA-signed, put by the ground) is applied by a running
    bus: what the revoked identity signs is refused from then on. A roster the CA did not
    sign changes nothing, and an older roster replayed revives no one."""
    write_identities(tmp_path, ["router", "ground", "uav-74", "uav-112"], [])
    older = roster_document(tmp_path)

    def bus(identity: str) -> ZenohBus:
        made = connect(endpoint)
        made.signing = bus_signing(tmp_path, identity, ca_pem=tmp_path / "ca.pem")
        return made

    ground, uav = bus("ground"), bus("uav-112")
    try:
        heard: list[str] = []
        uav.subscribe(SPACE.all_mission_results, lambda sample: heard.append(sample.key))
        assert uav.signing is not None
        revoke(tmp_path, ["uav-74"])
        forged = json.loads(roster_document(tmp_path))
        forged["revoked"] = ["uav-112"]
        before = refused("bad_signature")

        def forged_put_and_refused() -> bool:
            # Put again until refused: the router may not know the UAV's roster
            # subscription yet, and a put it does not know to route is lost.
            ground.put(SPACE.roster(), json.dumps(forged).encode())  # not the CA's
            return refused("bad_signature") > before

        wait_until(forged_put_and_refused, TIMEOUT_S * 5, "the forged roster refused")
        assert "uav-112" not in uav.signing.roster.revoked
        ground.put(SPACE.roster(), roster_document(tmp_path))
        wait_until(lambda: "uav-74" in uav.signing.roster.revoked, TIMEOUT_S * 5, "revoked")  # type: ignore[union-attr]
        assert "uav-112" not in uav.signing.roster.revoked
        ground.put(SPACE.roster(), older)
        assert uav.signing.apply_roster(SPACE.roster(), older) == frozenset()
        assert "uav-74" in uav.signing.roster.revoked
    finally:
        ground.close()
        uav.close()
