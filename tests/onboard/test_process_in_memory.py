"""One onboard process's answers on the bus, in the test's process: the real onboard
process logic and a simulated autopilot on the in-process bus
(tests/support/memory_world.py), the test as the ground station. What needs a process
or a real link (the serial link dropped, the payload port) is
tests/onboard/test_process.py."""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import msgspec
import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    CommandResult,
    MissionTargets,
    OpmCommand,
    Target,
    UavResult,
    UavState,
)
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from fleet.transport.bus import Bus, BusSample, decode_sample
from fleet.transport.bus_codec import encode
from onboard.bus_edge import standing_selector
from tests.support.ground_view import GroundView
from tests.support.memory_world import SPEEDUP, memory_fleet
from tests.support.waiting import wait_until

SPACE = KeySpace()

UAV = 112


@contextmanager
def single_uav(speedup: float = SPEEDUP) -> Iterator[tuple[Bus, GroundView]]:
    """UAV 112 of `single_uav` in memory, a ground's bus and what it sees, once the ground
    sees its telemetry."""
    with memory_fleet("single_uav", speedup=speedup) as fleet:
        ground = fleet.bus()
        seen = GroundView.on_bus(ground)
        try:
            wait_until(lambda: UAV in seen.telemetry, 30.0, f"telemetry from UAV {UAV}")
            yield ground, seen
        finally:
            seen.close()


def command(ground: Bus, name: str, payload: bytes) -> CommandResult:
    (reply,) = ground.query(SPACE.command(UAV, name), 5.0, payload)
    assert reply.ok, reply.payload
    return msgspec.json.decode(reply.payload, type=CommandResult)


def state(ground: Bus) -> UavState:
    ((_, answer),) = ground.query_messages(SPACE.state(UAV), UavState, 5.0)
    return answer


def test_state_query_answers_with_telemetry_and_link_health() -> None:
    # Fast, so that the first waypoint change (what sets the tracked one) comes soon.
    with single_uav(speedup=60.0) as (ground, seen):
        wait_until(lambda: seen.latest_track(UAV) is not None, 30.0, "telemetry and track")
        (reply,) = ground.query(SPACE.state(UAV), 5.0)
        assert reply.ok and reply.encoding.startswith("application/json")
        answer = state(ground)
        assert answer.uav == UAV and answer.enabled
        assert answer.telemetry is not None and answer.telemetry.gps is not None
        assert abs(answer.telemetry.gps.lat - 35.72) < 0.05
        assert answer.link is not None and answer.link.program_up and answer.link.packets > 0
        assert answer.tracked_waypoint == seen.latest_track(UAV)


def test_telemetry_reaches_the_bus_at_the_rate_asked_for() -> None:
    """20 Hz from the autopilot, --telemetry-hz 2 on the bus: about one sample in ten."""
    with memory_fleet("single_uav", speedup=1.0, telemetry_hz=20.0, relay_hz=2.0) as fleet:
        seen = GroundView.on_bus(fleet.bus())
        try:
            wait_until(lambda: len(seen.telemetry.get(UAV, [])) >= 6, 30.0, "6 samples")
            with seen.lock:
                samples = [t.system_time_ms for t in seen.telemetry[UAV]]
        finally:
            seen.close()
    # Relayed at most every 500 ms of the module's clock. A busy machine can bunch the
    # packets (two relayed samples closer in autopilot time), but over the whole span
    # no more than one every 500 ms gets through, where 20 Hz would be ten.
    span_ms = samples[-1] - samples[0]
    assert len(samples) <= span_ms / 500 + 2, f"{len(samples)} samples in {span_ms} ms"


def test_commands_are_confirmed_by_the_autopilot_echo() -> None:
    with single_uav() as (ground, seen):
        waypoint = Waypoint(index=42, next_index=0, lat=35.73, lon=-120.77, alt=650.0)
        result = command(ground, "waypoint", encode(waypoint))
        assert result.ok and result.attempts >= 1
        assert command(ground, "track", encode(Track(42))).ok
        wait_until(lambda: seen.latest_track(UAV) == 42, 10.0, "tracking waypoint 42")


def test_bad_command_and_bad_messages_are_refused_and_the_module_keeps_serving(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING)
    with single_uav() as (ground, _):
        (reply,) = ground.query(SPACE.command(UAV, "track"), 5.0, b'{"waypoint": "north"}')
        assert not reply.ok and b"not a valid Track" in reply.payload
        bad = {
            "OpmCommand": (SPACE.opm(UAV), b"\xff not json"),
            "MissionTargets": (SPACE.mission_targets(77), b'{"mission": 77}'),
        }
        for kind, (key, payload) in bad.items():

            def dropped(kind: str = kind) -> bool:
                return any("dropped" in m and kind in m for m in caplog.messages)

            ground.put(key, payload)
            wait_until(dropped, 10.0, f"the bad {kind} reported dropped")
        answer = state(ground)
        assert answer.enabled and answer.mission is None


def test_state_says_when_the_model_is_built_at_the_cruise_speed() -> None:
    with single_uav() as (ground, _):
        wait_until(lambda: state(ground).model_speed is not None, 60.0, "the model built")
        built = state(ground)
        assert built.telemetry is not None and built.telemetry.gps is not None
        cruise = math.hypot(built.telemetry.gps.vel_east, built.telemetry.gps.vel_north)
        assert built.model_speed == pytest.approx(cruise, abs=1.0)


def test_status_is_sent_on_change_and_the_periodic_report_is_the_state() -> None:
    with single_uav() as (ground, seen):
        states: list[UavState] = []
        lock = threading.Lock()
        statuses_before = len(seen.statuses(UAV))

        def on_state(sample: BusSample) -> None:
            state = decode_sample(sample, UavState)
            if state is not None:
                with lock:
                    states.append(state)

        subscription = ground.subscribe(SPACE.state(UAV), on_state)
        try:
            # Three periodic reports (1 s apart at the default rate) of an idle UAV...
            wait_until(lambda: len(states) >= 3, 30.0, "three periodic state reports")
        finally:
            subscription.undeclare()
        with lock:
            assert all(state.uav == UAV and state.telemetry is not None for state in states)
        # ...and, nothing having happened, not one status message in between.
        assert seen.statuses(UAV)[statuses_before:] == []


def test_module_off_refuses_to_write_and_says_so() -> None:
    with single_uav() as (ground, seen):
        ground.publish(SPACE.opm(UAV), OpmCommand(False, 2.0))
        wait_until(
            lambda: any("module off" in s for s in seen.statuses(UAV)), 10.0, "the off status"
        )
        result = command(ground, "track", encode(Track(1)))
        assert not result.ok and "off" in result.detail


def test_malformed_targets_give_a_status_error_naming_the_problem() -> None:
    with single_uav() as (ground, seen):
        bad = MissionTargets(mission=5, team=(UAV,), targets=(Target(35.7, 200.0, 600.0),))
        ground.publish(SPACE.mission_targets(5), bad)
        wait_until(
            lambda: any("longitude 200.0" in s for s in seen.statuses(UAV)), 10.0, "the error"
        )
        assert UAV not in seen.assignments


def test_a_teammates_standing_is_relayed_to_a_query_naming_it_and_its_plan() -> None:
    """An ask for a re-plan in changed air is believed from the asker's own standing
    only, and the asker may be gone: UAV 112 relays teammate 74's standing (as it signed
    it, under the secure profile) to a query naming 74 and the plan; nothing else."""
    targets = (Target(35.72, -120.76, 600.0), Target(35.73, -120.75, 600.0))
    mission = MissionTargets(mission=7, team=(74, UAV), targets=targets)
    standing = UavResult(7, 74, (100.0, 120.0), basis="b" * 16, asked=1)
    named = standing_selector(SPACE.mission_result(7, 74), "b" * 16)
    with single_uav() as (ground, _):
        ground.publish(SPACE.mission_targets(7), mission)

        def relayed() -> bool:
            ground.publish(SPACE.mission_result(7, 74), standing)  # again: it may be early
            return ground.query_messages(named, UavResult, 2.0) == [
                (SPACE.mission_result(7, 74), standing)
            ]

        wait_until(relayed, 30.0, "UAV 112 relaying 74's standing")
        # Not for another plan, nor to a query for every UAV's (each answers its own).
        other = standing_selector(SPACE.mission_result(7, 74), "c" * 16)
        assert ground.query_messages(other, UavResult, 2.0) == []
        every = standing_selector(SPACE.mission_results(7), "b" * 16)
        assert ground.query_messages(every, UavResult, 2.0) == []
