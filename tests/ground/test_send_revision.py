"""`send-targets --wait` serves its mission as it is now: a revision put while it runs
(`add-targets`, the page) replaces the one it sent, so a UAV that joins late fetches the
mission as changed (in-memory bus, a fake UAV that never commits)."""

from __future__ import annotations

import io
import threading

from fleet.consensus.mission_change import next_revision
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from fleet.transport.memory import MemoryNetwork
from ground.send_command import SendOptions, run_send_targets
from tests.ground.memory_fleet import MemoryUav
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
TARGETS = ring_targets(3, seed=5)
MISSION = 7
WAIT_S = 30.0


def test_a_revision_put_while_send_targets_waits_is_what_it_serves() -> None:
    network = MemoryNetwork()
    MemoryUav(network, 74)  # live, answers its state, never commits
    ground, other = network.bus(), network.bus()
    options = SendOptions(targets=TARGETS, team=(74,), wait=True, mission=MISSION, timeout=300)
    sending = threading.Thread(
        target=run_send_targets, args=(ground, options, io.StringIO()), daemon=True
    )
    sending.start()

    def served() -> list[int]:
        return [
            targets.revision
            for _, targets in other.query_messages(
                SPACE.mission_targets(MISSION), MissionTargets, 1.0
            )
        ]

    wait_until(lambda: served() == [0], WAIT_S, "the mission served as sent")
    sent = MissionTargets(MISSION, (74,), TARGETS)
    changed = next_revision(sent, ring_targets(1, seed=6), (1,))
    other.publish(SPACE.mission_targets(MISSION), changed)
    wait_until(lambda: served() == [1], WAIT_S, "the changed mission served")
    # A later mission for the team ends the wait (superseded), and the serving with it.
    other.publish(SPACE.mission_targets(MISSION + 1), MissionTargets(MISSION + 1, (74,), TARGETS))
    sending.join(WAIT_S)
    assert not sending.is_alive()
    assert served() == []
