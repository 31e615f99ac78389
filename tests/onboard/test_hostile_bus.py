"""The onboard process against a hostile bus: deeply nested, huge, malformed and
key-forged messages on every key it listens to, and commands with hostile payloads.
It refuses and counts each (its state's link drops, `bus_*`), keeps serving, and then
flies a real mission as if nothing happened.
"""

from __future__ import annotations

from importlib.resources import files

import msgspec
import zenoh

from fleet.files.targets_io import read_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, UavResult, UavState
from fleet.transport.bus_codec import MAX_PAYLOAD_BYTES, encode
from tests.conftest import Ground
from tests.support.processes import Fleet
from tests.support.waiting import wait_until

SPACE = KeySpace()

DEPTH = 50_000  #: 300 kB: under the size limit, far over any nesting limit
NESTED = b'{"a":' * DEPTH + b"1" + b"}" * DEPTH
HUGE = b'"' + b"x" * (2 * MAX_PAYLOAD_BYTES) + b'"'


def state_of(ground: Ground, uav: int) -> UavState | None:
    for reply in ground.session.get(SPACE.state(uav), timeout=2.0):
        if reply.ok is not None:
            return msgspec.json.decode(reply.ok.payload.to_bytes(), type=UavState)
    return None


def bus_drops(ground: Ground, uav: int) -> dict[str, int]:
    state = state_of(ground, uav)
    if state is None or state.link is None:
        return {}
    return {k: v for k, v in state.link.drops.items() if k.startswith("bus_")}


def test_onboard_refuses_counts_and_keeps_flying(fleet: Fleet, ground: Ground) -> None:
    endpoints = fleet.sim("single_uav", speedup=10.0, telemetry_hz=5.0)
    onboard = fleet.onboard(112, endpoints[112], ground.router)
    wait_until(lambda: 112 in ground.seen.telemetry, 30.0, "telemetry from UAV 112")
    session = ground.session
    token = session.liveliness().declare_token("fleet/uav/99999/alive")
    try:
        for key in (SPACE.mission_targets(5), SPACE.mission_abort(5), SPACE.opm(112)):
            for payload in (NESTED, HUGE):
                # Blocking: a large put may otherwise be dropped when the queue is full.
                session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)
        # Blocking too: behind the large puts, a small one may otherwise be dropped, and
        # the drop it should cause never counted.
        block = zenoh.CongestionControl.BLOCK
        result = encode(UavResult(5, 112, (1.0,)))
        session.put(SPACE.mission_result(5, 74), result, congestion_control=block)
        session.put(SPACE.mission_targets(6), b'{"mission": "six"}', congestion_control=block)
        for payload in (NESTED, HUGE):
            replies = list(session.get(SPACE.command(112, "waypoint"), payload=payload, timeout=5))
            assert replies and replies[0].err is not None  # refused, with the reason
        expected = {"bus_too_deep", "bus_too_large", "bus_wrong_key", "bus_invalid"}
        wait_until(
            lambda: expected <= set(bus_drops(ground, 112)),
            20.0,
            f"the drops counted: {sorted(expected)}",
        )
    finally:
        token.undeclare()
    assert onboard.process.poll() is None

    targets = tuple(read_targets(str(files("fleet") / "scenarios" / "single_uav_targets.bin")))
    ground.send(MissionTargets(mission=1, team=(112,), targets=targets, deadline_s=10.0))
    wait_until(lambda: 112 in ground.seen.assignments, 30.0, "UAV 112's assignment")
    assert ground.seen.assignments[112].target == 1  # as without the rogue
    assert onboard.process.poll() is None
