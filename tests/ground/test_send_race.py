"""Two operators send missions to one team a moment apart: `send-targets --wait` run as
two grounds in the test's process against a whole fleet in memory (real onboards,
simulated autopilots, the in-process bus; tests/support/memory_world.py).

Unheld, the team commits to the first mission in tens of milliseconds, before the
second ground has chosen its id (which is then higher, no collision), and then switches
to the second. Held (each ground's targets reach the team a second late, through the
fault-injecting bus, so both missions are out before the team sees either), the two
grounds may choose one id, a contest. Either way exactly one ground reports success:
the other says it was superseded.
"""

from __future__ import annotations

import io
import json
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport
from fleet.transport.bus import BusSample, decode_sample
from fleet.transport.bus_factory import open_bus
from fleet.transport.faulty_bus import FaultRule
from ground.send_command import SendOptions, run_send_targets
from tests.support.memory_world import memory_fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
#: How long a ground may take; generous for a loaded machine.
SEND_S = 120.0


@pytest.mark.parametrize("apart_s", [0.05, 0.5])
def test_two_grounds_racing_an_unheld_team_exactly_one_reports_success(
    tmp_path: Path, apart_s: float
) -> None:
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(2))
    with memory_fleet(str(scenario)) as fleet:
        team = list(fleet.ids)
        latest: dict[int, AssignmentReport] = {}
        lock = threading.Lock()

        def on_assignment(sample: BusSample) -> None:
            report = decode_sample(sample, AssignmentReport)
            if report is not None:
                with lock:
                    latest[report.uav] = report

        fleet.bus().subscribe(f"{SPACE.prefix}/mission/*/assignment/*", on_assignment)
        outs = [io.StringIO(), io.StringIO()]
        statuses: list[int | None] = [None, None]

        def send(index: int, seed: int) -> None:
            options = SendOptions(
                targets=ring_targets(2, seed=seed),
                wait=True,
                json=True,
                deadline=10.0,
                timeout=60.0,
            )
            statuses[index] = run_send_targets(fleet.bus(), options, outs[index])

        grounds = [threading.Thread(target=send, args=(0, 11))]
        grounds[0].start()
        time.sleep(apart_s)  # the fault: a second operator, a moment later
        grounds.append(threading.Thread(target=send, args=(1, 12)))
        grounds[1].start()
        for ground in grounds:
            ground.join(SEND_S)
        assert not any(ground.is_alive() for ground in grounds)
        reports: list[dict[str, Any]] = [json.loads(out.getvalue()) for out in outs]
        missions = [report["mission"] for report in reports]
        assert missions[0] != missions[1], reports
        later = max(missions)

        # The team flies the later mission: each UAV's latest commitment is to it.
        def all_on_later() -> bool:
            with lock:
                return all(uav in latest and latest[uav].mission == later for uav in team)

        wait_until(all_on_later, 10.0, f"every UAV committed to mission {later}")
    winner, loser = sorted(range(2), key=lambda i: reports[i]["mission"] != later)
    assert (reports[winner]["success"], reports[winner]["superseded_by"]) == (True, None)
    assert statuses[winner] == 0
    assert (reports[loser]["success"], reports[loser]["superseded_by"]) == (False, later)
    assert statuses[loser] == 1


#: How late each ground's targets reach the team when it is held.
HOLD_S = 1.5


@pytest.mark.parametrize("apart_s", [0.0, 0.05])
def test_two_send_targets_at_once_get_different_ids_and_the_superseded_one_says_so(
    tmp_path: Path, apart_s: float
) -> None:
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(2))
    held = FaultRule(SPACE.all_mission_targets, delay_s=HOLD_S)
    with memory_fleet(str(scenario)) as fleet:
        team = list(fleet.ids)
        outs = [io.StringIO(), io.StringIO()]
        statuses: list[int | None] = [None, None]

        def send(index: int, seed: int) -> None:
            targets = ring_targets(2, seed=seed)
            options = SendOptions(
                targets=targets, wait=True, json=True, deadline=10.0, timeout=60, query_timeout=0.3
            )
            bus = open_bus(fleet.spec, faults=[held])
            try:
                statuses[index] = run_send_targets(bus, options, outs[index])
            finally:
                bus.close()

        grounds = [threading.Thread(target=send, args=(0, 11))]
        grounds[0].start()
        time.sleep(apart_s)  # the fault: a second operator, a moment later
        grounds.append(threading.Thread(target=send, args=(1, 12)))
        grounds[1].start()
        for ground in grounds:
            ground.join(SEND_S)
        assert not any(ground.is_alive() for ground in grounds)
    reports: list[dict[str, Any]] = [json.loads(out.getvalue()) for out in outs]
    missions = [report["mission"] for report in reports]
    assert missions[0] != missions[1], reports
    later = max(missions)
    winner, loser = sorted(range(2), key=lambda i: reports[i]["mission"] != later)
    # The later mission is the one the team flies: it agreed, and says so.
    assert reports[winner]["superseded_by"] is None
    assert reports[winner]["success"] is True
    assert statuses[winner] == 0
    # The earlier one is reported superseded by it: no success, a non-zero exit.
    assert reports[loser]["superseded_by"] == later
    assert reports[loser]["success"] is False
    assert {s["state"] for s in reports[loser]["target_states"]} <= {"unserved", "reached"}
    assert statuses[loser] == 1
    assert sorted(reports[winner]["taking_part"]) == team
