"""Mission traffic and commands outrank telemetry on the bus (fleet.transport.bus_qos)."""

from __future__ import annotations

import zenoh

from fleet.mission import keys
from fleet.transport.bus_qos import ORDINARY, TELEMETRY, URGENT, qos_for


def test_mission_messages_and_commands_are_urgent_and_never_dropped() -> None:
    for key in (
        keys.mission_targets(3),
        keys.mission_result(3, 74),
        keys.mission_assignment(3, 74),
        keys.mission_abort(3),
        keys.opm(74),
    ):
        assert qos_for(key) == URGENT, key
    assert URGENT.congestion_control == zenoh.CongestionControl.BLOCK
    assert URGENT.priority == zenoh.Priority.INTERACTIVE_HIGH


def test_telemetry_is_least_urgent_and_dropped_under_congestion() -> None:
    assert qos_for(keys.telemetry(74)) == TELEMETRY
    assert TELEMETRY.congestion_control == zenoh.CongestionControl.DROP
    assert TELEMETRY.priority == zenoh.Priority.DATA_LOW
    assert qos_for(keys.status(74)) == ORDINARY


def test_the_key_prefix_in_use_decides() -> None:
    previous = keys.PREFIX
    try:
        keys.use_prefix("lab")
        assert qos_for(keys.mission_targets(1)) == URGENT
        assert qos_for("fleet/mission/1/targets") == ORDINARY  # another prefix's key
    finally:
        keys.use_prefix(previous)
