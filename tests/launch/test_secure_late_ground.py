"""A ground that joins late believes a reached target only from the reaching UAV's own
signed outcome. A secure fleet of real processes (the router with mutual TLS and access
control, the simulator, onboards 74 and 112) flies a mission until one UAV reaches a
target; then its teammate's key (captured) lies about it, by its own signed outcome and
by forged and tampered relays of the reacher's, and a new `ground-cli mission` catches up.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator

import msgspec
import pytest
import zenoh

from fleet.mission.messages import TargetOutcome, UavState
from fleet.mission.phase import Phase
from fleet.transport.bus_codec import ENCODING, decode, encode
from tests.support import signed
from tests.support.secure_fleet import SPACE, SignedFleet, signed_fleet
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

#: Fast enough that a UAV reaches its first target within a minute or so.
SPEEDUP = 8.0


@pytest.fixture(scope="module")
def secure(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SignedFleet]:
    certs = tmp_path_factory.mktemp("certs").resolve()
    names = ["router", "ground", "uav-74", "uav-112"]
    with signed_fleet(certs, names, speedup=SPEEDUP) as fleet:
        yield fleet


class Outcomes:
    """Every outcome put on the mission's keys, with its envelope, as a router sees them."""

    def __init__(self, session: zenoh.Session, mission: int) -> None:
        self.heard: list[tuple[str, bytes, bytes]] = []
        self.lock = threading.Lock()
        self.subscriber = session.declare_subscriber(SPACE.mission_outcomes(mission), self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
        with self.lock:
            self.heard.append((str(sample.key_expr), sample.payload.to_bytes(), attachment))

    def latest(self, key: str) -> tuple[bytes, bytes] | None:
        with self.lock:
            found = [(payload, sig) for k, payload, sig in self.heard if k == key]
        return found[-1] if found else None


def reached_own(state: UavState | None) -> int | None:
    """A target `state`'s UAV says it reached itself, if any."""
    if state is None or state.mission is None:
        return None
    own = [t for t, uav in state.mission.reached.items() if uav == state.uav]
    return own[0] if own else None


def test_a_late_ground_believes_a_reached_target_only_from_its_reacher(
    secure: SignedFleet,
) -> None:
    """Mission sent; UAV X reaches target R (its own signed outcome says so). Its
    teammate A's key then claims, in A's own signed outcome, that X reached T (a target
    not in X's queue: X never flies it), and answers a query naming X's outcome with a
    copy of X's outcome listing T, signed by A (not X's to sign), and with X's genuine
    envelope over that tampered list. A new `ground-cli mission` shows R reached by X,
    and T not reached by X."""
    mission = secure.send_targets()
    recorded = Outcomes(secure.ground, mission)
    states: dict[int, UavState | None] = {}

    def one_reached() -> bool:
        states.update({uav: secure.state(uav) for uav in (74, 112)})
        return any(reached_own(state) is not None for state in states.values())

    wait_until(one_reached, 240.0, "a UAV reaching its first target")
    reacher = next(uav for uav, state in states.items() if reached_own(state) is not None)
    other = 186 - reacher  # 74 <-> 112
    reached = reached_own(states[reacher])
    state = states[reacher]
    assert reached is not None and state is not None and state.mission is not None
    report = state.mission.assignment
    assert report is not None
    queue = set(report.queues.get(reacher) or (report.pairs[reacher],))
    never = next(t for t in range(3) if t not in queue)  # X never flies it

    own_key = SPACE.mission_outcome(mission, other)
    their_key = SPACE.mission_outcome(mission, reacher)
    wait_until(lambda: recorded.latest(their_key) is not None, 30.0, "X's outcome recorded")
    genuine = recorded.latest(their_key)
    assert genuine is not None
    genuine_payload, genuine_envelope = genuine
    theirs = decode(genuine_payload, TargetOutcome, their_key)
    lie = encode(TargetOutcome(mission, other, None, Phase.REACHED, reached={never: reacher}))
    listed = {**theirs.reached, never: reacher}
    tampered = encode(msgspec.structs.replace(theirs, reached=listed))
    by_other = f"uav-{other}"
    served: list[str] = []

    def serve(query: zenoh.Query) -> None:
        key = str(query.key_expr)
        if query.key_expr.intersects(zenoh.KeyExpr(own_key)):
            sig = signed.attachment(secure.certs, by_other, own_key, lie)
            query.reply(own_key, lie, encoding=ENCODING, attachment=sig)
        if key == their_key:  # a query naming X's outcome: what a relay answers
            forged = signed.attachment(secure.certs, by_other, their_key, tampered)
            query.reply(their_key, tampered, encoding=ENCODING, attachment=forged)
            query.reply(their_key, tampered, encoding=ENCODING, attachment=genuine_envelope)
            served.append(key)

    with secure.session(by_other) as attacker:
        queryable = attacker.declare_queryable(SPACE.mission_outcomes(mission), serve)
        sig = signed.attachment(secure.certs, by_other, own_key, lie)
        attacker.put(own_key, lie, encoding=ENCODING, attachment=sig)
        shown = secure.ground_cli("mission", "--mission", str(mission), "--json")
        queryable.undeclare()
    recorded.subscriber.undeclare()
    assert shown.returncode in (0, 1), shown.stderr[-3000:]
    targets = {s["index"]: s for s in json.loads(shown.stdout)["target_states"]}
    shown_reached = (targets[reached]["state"], targets[reached]["uav"])
    assert shown_reached == ("reached", reacher), targets
    assert not (targets[never]["state"] == "reached" and targets[never]["uav"] == reacher), (
        f"the late ground shows target {never} reached by {reacher} on {other}'s word: {targets}"
    )
    # The lie was a hint: the ground asked for X's own outcome by name, and was answered
    # the forgeries too.
    assert served, "the late ground never asked for X's own outcome"
