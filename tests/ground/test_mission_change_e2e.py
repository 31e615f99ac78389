"""The mission changed in flight, end to end: three onboard processes over Zenoh, the
simulator's aircraft, and `ground-cli add-targets` / `remove-targets` as an operator
runs them. Two targets added and one removed while the team flies: every target left is
reached exactly once (by the UAVs' own outcomes and the simulator's true positions), and
the removed one by nobody."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tests.conftest import Ground
from tests.ground.test_replan import REACH_TIMEOUT_S, SPEEDUP
from tests.ground.test_truth import targets_file
from tests.onboard.test_multi_uav import start_ring
from tests.support.ground_cli import finish_ground_cli, start_ground_cli
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

TARGETS = ring_targets(6, seed=7)
FIRST, LATER = TARGETS[:4], TARGETS[4:]
REACHED = re.compile(r"reached target (\d+) ")


def test_two_targets_added_and_one_removed_in_flight_are_flown_exactly_as_changed(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    team = start_ring(fleet, ground, tmp_path, 3, SPEEDUP, telemetry_hz=5.0)
    seen = ground.seen
    path = targets_file(tmp_path, FIRST)
    send = start_ground_cli(
        "send-targets", str(path), "--team", ",".join(map(str, team)), connect=ground.router
    )
    assert finish_ground_cli(send, 60)[0] == 0
    wait_until(lambda: set(team) <= set(seen.assignments), 60.0, "every commitment")
    plan = seen.assignments[team[0]]
    mission = plan.mission
    # Removed: a target nobody flies yet (second in a queue), else the latest to come.
    later = [q[1] for q in plan.queues.values() if len(q) > 1]
    arrivals = {t: a[i] for u, q in plan.queues.items() for i, t in enumerate(q)
                for a in (plan.arrivals.get(u, ()),) if i < len(a)}  # fmt: skip
    gone = later[0] if later else max(arrivals, key=arrivals.__getitem__)

    extra = tmp_path / "later"
    extra.mkdir()
    add = start_ground_cli(
        "add-targets", str(targets_file(extra, LATER)), "--mission", str(mission), "--json",
        connect=ground.router,
    )  # fmt: skip
    status, out, err = finish_ground_cli(add, 60)
    assert status == 0, err
    added = json.loads(out)
    assert added["added"] == [4, 5] and sorted(added["acknowledged"]) == sorted(team), added
    remove = start_ground_cli(
        "remove-targets", str(gone), "--mission", str(mission), "--json", connect=ground.router
    )
    status, out, err = finish_ground_cli(remove, 60)
    assert status == 0, err
    assert json.loads(out)["removed"] == [gone]
    wait_until(lambda: all(seen.assignments[uav].revision == 2 for uav in team), 30.0, "revision 2")
    assert all(gone not in q for q in seen.assignments[team[0]].queues.values())

    status, out, err = finish_ground_cli(
        start_ground_cli(
            "mission", "--mission", str(mission), "--until-reached", str(REACH_TIMEOUT_S),
            "--json", connect=ground.router,
        ),
        REACH_TIMEOUT_S + 60,
    )  # fmt: skip
    report = json.loads(out)
    states = {s["index"]: s for s in report["target_states"]}
    assert len(states) == 6, report
    assert states[gone]["state"] == "removed", err
    left = [t for t in range(6) if t != gone]
    assert all(states[t]["state"] == "reached" for t in left), err
    assert status == 0, err
    # Exactly once: each target left reached by one UAV, by its own word and in truth.
    said = [int(m.group(1)) for uav in team for s in seen.statuses(uav) if (m := REACHED.search(s))]
    assert sorted(said) == left, said
    for t in left:
        reacher = states[t]["uav"]
        assert seen.closest_approach(reacher, TARGETS[t].lat, TARGETS[t].lon) <= 75.0
