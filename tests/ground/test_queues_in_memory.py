"""Task queues by objective: `send-targets --wait --objective` from the ground's command
against three real onboards in memory (tests/support/memory_world.py): every UAV agrees
on one plan (one digest, the same queues, every target in exactly one), and the JSON
tells each target its holder, its place in that queue and its arrival. Flying the
queues to the end is tests/ground/test_queues_e2e.py."""

from __future__ import annotations

import io
import json
import threading
from pathlib import Path

import pytest

from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport
from fleet.mission.objective import Objective
from fleet.transport.bus import BusSample, decode_sample
from ground.send_command import SendOptions, run_send_targets
from tests.support.memory_world import memory_fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
TARGETS = ring_targets(8, seed=23)


@pytest.mark.parametrize("objective", [Objective.MIN_SUM, Objective.MIN_MAX])
def test_every_uav_agrees_on_the_plan_of_each_objective(
    tmp_path: Path, objective: Objective
) -> None:
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(3))
    with memory_fleet(str(scenario)) as fleet:
        team = list(fleet.ids)
        seen: dict[int, AssignmentReport] = {}
        lock = threading.Lock()

        def on_assignment(sample: BusSample) -> None:
            report = decode_sample(sample, AssignmentReport)
            if report is not None:
                with lock:
                    seen[report.uav] = report

        fleet.bus().subscribe(f"{SPACE.prefix}/mission/*/assignment/*", on_assignment)
        out = io.StringIO()
        options = SendOptions(
            targets=TARGETS, team=tuple(team), wait=True, json=True, objective=objective
        )
        assert run_send_targets(fleet.bus(), options, out) == 0
        report = json.loads(out.getvalue())
        assert report["agreed"] is True and report["complete"] is True
        wait_until(lambda: set(team) <= set(seen), 30.0, "every commitment")
        with lock:
            reports = {uav: seen[uav] for uav in team}
    # Every UAV agrees: one digest, the same queues, every target in exactly one queue.
    assert len({(r.digest, str(r.queues)) for r in reports.values()}) == 1
    queued = [t for q in reports[team[0]].queues.values() for t in q]
    assert sorted(queued) == list(range(len(TARGETS)))
    # The JSON tells each target its holder, its place in that queue and its arrival.
    for state in report["target_states"]:
        holder = state["uav"]
        queue = reports[team[0]].queues[holder]
        assert state["place"] == queue.index(state["index"]) + 1
        assert state["eta_s"] == pytest.approx(
            reports[team[0]].arrivals[holder][state["place"] - 1]
        )
    assert {str(r.objective) for r in reports.values()} == {str(objective)}
