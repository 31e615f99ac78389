"""The ground tells the truth under faults, in the test's process: the real onboard
process logic and simulated autopilots on the in-process bus
(tests/support/memory_world.py), `ground-cli` run by its root on that bus. The claims
here need no process; what does (a UAV killed or frozen, a dead serial link) is
tests/ground/test_truth.py."""

from __future__ import annotations

import json
from pathlib import Path

import msgspec

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import CommandResult
from fleet.piccolo.track import Track
from fleet.transport.bus_codec import encode
from tests.ground.test_truth import targets_file
from tests.support.ground_cli import ground_cli_here
from tests.support.ground_view import GroundView
from tests.support.memory_world import memory_fleet, ring_file
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()


def test_an_operator_retasking_a_uav_in_flight_is_preempted_not_reached_and_abortable(
    tmp_path: Path,
) -> None:
    with memory_fleet(ring_file(tmp_path, 1), speedup=2.0) as fleet:
        (uav,) = fleet.ids
        ground = fleet.bus()
        seen = GroundView.on_bus(ground)
        try:
            path = targets_file(tmp_path, ring_targets(1, seed=4))
            sent = ground_cli_here("send-targets", str(path), connect=fleet.spec)
            assert sent.returncode == 0, sent.stderr
            wait_until(
                lambda: any("flying to target 0" in s for s in seen.statuses(uav)), 60.0, "flying"
            )
            # The fault: an operator re-tasks the aircraft to waypoint 1 while it flies.
            (reply,) = ground.query(SPACE.command(uav, "track"), 10.0, encode(Track(1)))
            assert reply.ok, reply.payload
            answer = msgspec.json.decode(reply.payload, type=CommandResult)
            assert answer.ok, answer
            done = ground_cli_here("uavs", "--json", connect=fleet.spec)
            (row,) = json.loads(done.stdout)
            assert row["phase"] == "preempted", row
            assert "track to waypoint 1" in row["reason"]
            wait_until(lambda: seen.latest_track(uav) == 1, 30.0, "the aircraft on waypoint 1")
            assert not any(s.startswith("reached") for s in seen.statuses(uav))
            done = ground_cli_here("abort", connect=fleet.spec)
            # the abort is obeyed and confirmed in that state too
            assert done.returncode == 0, done.stdout + done.stderr
        finally:
            seen.close()
