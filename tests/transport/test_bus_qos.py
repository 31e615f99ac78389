"""Mission traffic and commands outrank telemetry on the bus (fleet.transport.bus_qos)."""

from __future__ import annotations

import queue

import zenoh

from fleet.mission.key_space import KeySpace
from fleet.transport import bus_qos
from fleet.transport.bus_codec import ENCODING
from fleet.transport.bus_qos import ORDINARY, TELEMETRY, URGENT, qos_for
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import make_config
from tests.support.processes import client_session, router_session

SPACE = KeySpace()


def test_mission_messages_and_commands_are_urgent_and_never_dropped() -> None:
    for key in (
        SPACE.mission_targets(3),
        SPACE.mission_result(3, 74),
        SPACE.mission_assignment(3, 74),
        SPACE.mission_abort(3),
        SPACE.opm(74),
    ):
        assert qos_for(key) == URGENT, key
    assert URGENT.congestion_control == zenoh.CongestionControl.BLOCK
    assert URGENT.priority == zenoh.Priority.INTERACTIVE_HIGH
    assert not URGENT.express  # a team's commits fan out batched (see bus_qos)


def test_telemetry_is_least_urgent_and_dropped_under_congestion() -> None:
    assert qos_for(SPACE.telemetry(74)) == TELEMETRY
    assert TELEMETRY.congestion_control == zenoh.CongestionControl.DROP
    assert TELEMETRY.priority == zenoh.Priority.DATA_LOW
    assert qos_for(SPACE.status(74)) == ORDINARY


def test_the_key_own_prefix_decides() -> None:
    lab = KeySpace("lab")
    assert qos_for(lab.mission_targets(1)) == URGENT
    assert qos_for(lab.telemetry(1)) == TELEMETRY
    assert qos_for("re.play/mission/1/targets") == ORDINARY  # not a key prefix


def test_a_key_space_given_decides() -> None:
    lab = KeySpace("lab")
    assert qos_for(lab.mission_targets(1), lab) == URGENT
    assert qos_for(lab.telemetry(1), lab) == TELEMETRY
    assert qos_for(SPACE.mission_targets(1), lab) == ORDINARY


def test_telemetry_goes_through_one_declared_publisher_with_its_qos() -> None:
    """ZenohBus puts telemetry on a publisher declared once (half the CPU of a
    session put); what arrives is every sample, with telemetry's priority and encoding."""
    received: queue.SimpleQueue[zenoh.Sample] = queue.SimpleQueue()
    with router_session() as router, client_session(router.endpoints[0]) as listener:
        subscriber = listener.declare_subscriber(f"{SPACE.prefix}/uav/*/*", received.put)
        bus = ZenohBus(zenoh.open(make_config("client", router.endpoints)))
        try:
            wait_until_matched(bus, SPACE.telemetry(74))
            for n in range(3):
                bus.put(SPACE.telemetry(74), f"{n}".encode())
            bus.put(SPACE.status(74), b"status")
            samples = [received.get(timeout=5.0) for _ in range(4)]
            assert len(bus._publishers) == 1  # the status line went by session put
        finally:
            bus.close()
            subscriber.undeclare()
    telemetry = [s for s in samples if str(s.key_expr) == SPACE.telemetry(74)]
    assert [s.payload.to_bytes() for s in telemetry] == [b"0", b"1", b"2"]
    assert all(s.priority == zenoh.Priority.DATA_LOW for s in telemetry)
    assert all(str(s.encoding) == str(ENCODING) for s in telemetry)


def wait_until_matched(bus: ZenohBus, key: str) -> None:
    """Until the router knows the listener's subscription (a put before it is dropped)."""
    publisher = bus_qos.declare(bus.session, key)
    changes: queue.SimpleQueue[bool] = queue.SimpleQueue()
    listener = publisher.declare_matching_listener(lambda status: changes.put(status.matching))
    try:
        # The stub says bool; zenoh 1.10 returns a MatchingStatus.
        matched = bool(getattr(publisher.matching_status, "matching", False))
        while not matched:
            matched = changes.get(timeout=10.0)
    finally:
        listener.undeclare()
        publisher.undeclare()
