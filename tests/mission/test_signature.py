"""Signed messages, pure: the envelope, who must sign which key, signatures, freshness."""

from __future__ import annotations

import msgspec
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from hypothesis import given
from hypothesis import strategies as st

from fleet.mission import signature
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import UavResult
from fleet.mission.signature import Delivery, Envelope, Freshness, Refusal, Roster, sign, verify
from fleet.transport.bus_codec import encode

SPACE = KeySpace()
S = 1_000_000_000
NOW = 1_800_000_000 * S
KEYS = {
    name: Ed25519PrivateKey.generate()
    for name in ("ground", "uav-74", "uav-112", "router", "router-74")
}
ROSTER = Roster({name: key.public_key() for name, key in KEYS.items()})


def signed(author: str, key: str, payload: bytes, at: int = NOW) -> bytes:
    return sign(KEYS[author], author, key, payload, at)


def test_the_envelope_round_trips_and_garbage_is_no_envelope() -> None:
    envelope = Envelope("uav-74", 123, bytes(range(64)))
    assert Envelope.decode(envelope.encode()) == envelope
    assert Envelope.decode(envelope.encode()[:-1]) is None
    assert Envelope.decode(b"") is None
    assert Envelope.decode(b"fsig1\x00") is None


@given(st.binary(max_size=200))
def test_any_attachment_decodes_or_is_refused_never_raises(data: bytes) -> None:
    Envelope.decode(data)
    Envelope.decode(signature.MAGIC + data)
    verify(ROSTER, SPACE, SPACE.mission_abort(5), b"{}", data, Delivery.PUT)


def test_who_must_sign_follows_the_registry() -> None:
    put, reply, query = Delivery.PUT, Delivery.REPLY, Delivery.QUERY
    assert signature.author_of(SPACE, SPACE.mission_targets(5), put) == "ground"
    # A teammate relaying the mission or its abort relays the ground's message.
    assert signature.author_of(SPACE, SPACE.mission_targets(5), reply) == "ground"
    assert signature.author_of(SPACE, SPACE.mission_abort(5), reply) == "ground"
    assert signature.author_of(SPACE, SPACE.opm(112), put) == "ground"
    assert signature.author_of(SPACE, SPACE.command(112, "waypoint"), query) == "ground"
    # The autopilot command's result is the UAV's own answer.
    assert signature.author_of(SPACE, SPACE.command(112, "waypoint"), reply) == "uav-112"
    for key in (
        SPACE.mission_result(5, 112),
        SPACE.mission_assignment(5, 112),
        SPACE.mission_replan(5, 112),
        SPACE.mission_outcome(5, 112),
        SPACE.state(112),
    ):
        assert signature.author_of(SPACE, key, put) == "uav-112", key
        assert signature.author_of(SPACE, key, reply) == "uav-112", key
    # Telemetry and the like are not signed; a query's payload is a command only on
    # the command keys; keys outside the registry are not checked here.
    assert signature.author_of(SPACE, SPACE.telemetry(112), put) is None
    assert signature.author_of(SPACE, SPACE.mission_targets(5), query) is None
    assert signature.author_of(SPACE, "fleet/else/where", put) is None


def test_a_message_signed_by_its_author_is_believed() -> None:
    key, payload = SPACE.mission_targets(5), b'{"mission": 5}'
    envelope, refusal = verify(
        ROSTER, SPACE, key, payload, signed("ground", key, payload), Delivery.REPLY
    )
    assert refusal is None and envelope is not None and envelope.author == "ground"
    assert verify(ROSTER, SPACE, SPACE.telemetry(74), b"{}", b"", Delivery.PUT) == (None, None)


def test_a_routers_state_is_signed_by_a_router_for_itself() -> None:
    """Any router answers `router/state` for itself: its own identity signs the answer
    (shown as its word); a UAV's identity, or none, cannot."""
    key, payload = SPACE.router_state(), b'{"zid": "aa", "refused_links": {}}'
    assert signature.author_of(SPACE, key, Delivery.REPLY) == signature.ANY_ROUTER
    for router in ("router", "router-74"):
        envelope, refusal = verify(
            ROSTER, SPACE, key, payload, signed(router, key, payload), Delivery.REPLY
        )
        assert refusal is None and envelope is not None and envelope.author == router
    by_uav = verify(ROSTER, SPACE, key, payload, signed("uav-74", key, payload), Delivery.REPLY)
    assert by_uav[1] is Refusal.NOT_ENTITLED
    assert verify(ROSTER, SPACE, key, payload, b"", Delivery.REPLY)[1] is Refusal.UNSIGNED


def test_forgeries_are_refused_each_for_its_reason() -> None:
    key, payload = SPACE.mission_targets(4_000_000_000), b'{"mission": 4000000000}'
    by_74 = signed("uav-74", key, payload)

    def why(attachment: bytes, roster: Roster = ROSTER, on: str = key) -> Refusal | None:
        return verify(roster, SPACE, on, payload, attachment, Delivery.REPLY)[1]

    assert why(b"") is Refusal.UNSIGNED
    assert why(b"not an envelope") is Refusal.MALFORMED
    # UAV 74 serving a mission of its own making, signed with its own key.
    assert why(by_74) is Refusal.NOT_ENTITLED
    by_ground = signed("ground", key, payload)
    # The ground's signature, moved to another key or over another payload.
    assert why(by_ground, on=SPACE.mission_targets(6)) is Refusal.BAD_SIGNATURE
    tampered = verify(ROSTER, SPACE, key, payload + b" ", by_ground, Delivery.REPLY)[1]
    assert tampered is Refusal.BAD_SIGNATURE
    stranger = Ed25519PrivateKey.generate()
    assert why(sign(stranger, "uav-999", key, payload, NOW)) is Refusal.UNKNOWN_AUTHOR
    # A key pair claiming to be the ground's.
    assert why(sign(stranger, "ground", key, payload, NOW)) is Refusal.BAD_SIGNATURE
    revoked = Roster(ROSTER.keys, frozenset({"uav-74"}))
    own = SPACE.mission_result(5, 74)
    assert (
        verify(revoked, SPACE, own, payload, signed("uav-74", own, payload), Delivery.PUT)[1]
        is Refusal.REVOKED
    )


def envelope_at(at: int, author: str = "ground") -> Envelope:
    return Envelope(author, at, bytes(64))


def test_a_live_message_must_be_fresh_and_new_on_its_key() -> None:
    fresh = Freshness(window_ns=30 * S)
    key = SPACE.opm(112)
    assert fresh.check(key, envelope_at(NOW - 40 * S), Delivery.PUT, NOW) is Refusal.STALE
    assert fresh.check(key, envelope_at(NOW + 40 * S), Delivery.PUT, NOW) is Refusal.STALE
    assert fresh.check(key, envelope_at(NOW - 2 * S), Delivery.PUT, NOW) is None
    assert fresh.check(key, envelope_at(NOW - 1 * S), Delivery.PUT, NOW) is None
    # "off" captured two seconds ago, replayed after "on": refused.
    assert fresh.check(key, envelope_at(NOW - 2 * S), Delivery.PUT, NOW) is Refusal.REPLAYED
    assert fresh.check(key, envelope_at(NOW - 1 * S), Delivery.PUT, NOW) is Refusal.REPLAYED
    # Another key, or another author, has its own mark.
    assert fresh.check(SPACE.opm(74), envelope_at(NOW - 2 * S), Delivery.PUT, NOW) is None


def test_each_receiver_believes_a_message_once() -> None:
    """One message reaches every subscription of a process it matches (a recorder's
    `fleet/**` and the bus's own digest subscription): each believes it, once."""
    fresh = Freshness(window_ns=30 * S)
    digest = SPACE.digest(112)
    message = envelope_at(NOW - S, "uav-112")
    assert fresh.check(digest, message, Delivery.PUT, NOW, receiver=1) is None
    assert fresh.check(digest, message, Delivery.PUT, NOW, receiver=2) is None
    assert fresh.check(digest, message, Delivery.PUT, NOW, receiver=1) is Refusal.REPLAYED
    assert fresh.check(digest, message, Delivery.PUT, NOW, receiver=2) is Refusal.REPLAYED


def test_a_command_signed_before_the_process_started_is_a_replay_after_a_restart() -> None:
    """The marks are in memory: a process started at NOW refuses the ground's "OPM off"
    signed 14 s before (a replay across its restart), and takes the ones signed since.
    What is not a command (a teammate's result) and a caught-up reply are not judged so."""
    fresh = Freshness(window_ns=30 * S, floor_ns=NOW)
    later = NOW + 1 * S
    opm = SPACE.opm(112)
    assert fresh.check(opm, envelope_at(NOW - 14 * S), Delivery.PUT, later) is Refusal.REPLAYED
    assert fresh.check(opm, envelope_at(NOW + S // 2), Delivery.PUT, later) is None
    result = SPACE.mission_result(5, 74)
    assert fresh.check(result, envelope_at(NOW - 14 * S, "uav-74"), Delivery.PUT, later) is None
    targets = SPACE.mission_targets(5)
    assert fresh.check(targets, envelope_at(NOW - 14 * S), Delivery.REPLY, later) is None


def test_a_caught_up_message_may_be_old_but_an_abort_not_older_than_its_mission() -> None:
    fresh = Freshness(window_ns=30 * S)
    hour = 3600 * S
    targets, abort = SPACE.mission_targets(1), SPACE.mission_abort(1)
    # The mission was sent an hour ago; its abort half an hour ago: both believed late.
    assert fresh.check(targets, envelope_at(NOW - hour), Delivery.REPLY, NOW) is None
    assert fresh.check(abort, envelope_at(NOW - hour // 2), Delivery.REPLY, NOW) is None
    # An abort of an earlier mission 1 (before a fleet restart reused the id): refused.
    assert fresh.check(abort, envelope_at(NOW - 2 * hour), Delivery.REPLY, NOW) is Refusal.REPLAYED
    # An abort from a second ground station whose clock is 10 s behind the first's.
    assert fresh.check(abort, envelope_at(NOW - hour - 10 * S), Delivery.REPLY, NOW) is None
    # Its targets served again later (the ground's server signs each reply) change nothing.
    assert fresh.check(targets, envelope_at(NOW), Delivery.REPLY, NOW) is None
    assert fresh.check(abort, envelope_at(NOW - hour // 2), Delivery.REPLY, NOW) is None
    # Nothing from the future.
    assert fresh.check(abort, envelope_at(NOW + hour), Delivery.REPLY, NOW) is Refusal.STALE


def test_the_replay_marks_stay_bounded() -> None:
    fresh = Freshness(window_ns=30 * S)
    for n in range(signature.MAX_MARKS * 2):
        assert fresh.check(SPACE.opm(1 + n % 60000), envelope_at(NOW), Delivery.PUT, NOW) is None
    assert len(fresh._marks) <= signature.MAX_MARKS
    # Marks past the window go as time passes.
    fresh.check(SPACE.opm(1), envelope_at(NOW + 60 * S), Delivery.PUT, NOW + 60 * S)
    assert len(fresh._marks) == 1


def test_a_results_word_on_proposing_is_signed_with_it() -> None:
    """Whether a UAV will propose (UavResult.proposes) is signed with its result: a
    relay that turns its "no" into a "yes" (or back) breaks the signature."""
    key = SPACE.mission_result(5, 74)
    said = UavResult(5, 74, (10.0, 20.0), proposes=False)
    payload = encode(said)
    by_74 = signed("uav-74", key, payload)
    assert verify(ROSTER, SPACE, key, payload, by_74, Delivery.REPLY)[1] is None
    forged = encode(msgspec.structs.replace(said, proposes=True))
    assert forged != payload
    assert verify(ROSTER, SPACE, key, forged, by_74, Delivery.REPLY)[1] is Refusal.BAD_SIGNATURE
