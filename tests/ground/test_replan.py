"""Every target accounted for, end to end: a UAV holding a target is killed after the
commitment; its idle teammate re-plans, flies the orphaned target and reaches it, and
`ground-cli mission` shows the target reached by its new holder."""

from __future__ import annotations

import json
from pathlib import Path

from fleet.launch.launcher import ring_scenario
from tests.conftest import Ground
from tests.ground.test_truth import finish, ground_cli, targets_file
from tests.onboard.test_multi_uav import ring_targets, start_onboard, wait_for_telemetry
from tests.processes import Fleet, wait_until

#: Slow enough that the victim cannot reach its target before it is killed.
SPEEDUP = 3.0
REACH_TIMEOUT_S = 240.0


def test_the_idle_uav_flies_and_reaches_the_target_of_a_holder_killed_after_commit(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(3))
    endpoints = fleet.sim(str(scenario), SPEEDUP, 5.0)
    start_onboard(fleet, endpoints, ground.router)
    team = sorted(endpoints)
    wait_for_telemetry(ground, team)
    seen = ground.seen
    path = targets_file(tmp_path, ring_targets(2, seed=7))
    send = ground_cli(ground.router, "send-targets", str(path), "--team", ",".join(map(str, team)))
    assert finish(send, 60)[0] == 0
    wait_until(lambda: set(team) <= set(seen.assignments), 60.0, "three commitments")
    pairs = seen.assignments[team[0]].pairs
    holders = {int(uav): target for uav, target in pairs.items()}
    (idle,) = set(team) - set(holders)
    # The victim: the holder with the farther target, so it is still on its way.
    etas = {uav: seen.assignments[uav].eta_s or 0.0 for uav in holders}
    victim = max(holders, key=etas.__getitem__)
    orphan = holders[victim]
    (child,) = [c for c in fleet.children if c.name == f"onboard {victim}"]
    child.process.kill()  # liveliness goes with the TCP connection
    child.process.wait(10)

    wait_until(lambda: seen.assignments[idle].epoch == 1, 30.0, f"UAV {idle} re-planning epoch 1")
    replanned = seen.assignments[idle]
    assert replanned.target == orphan and replanned.released == (victim,)
    survivor = next(uav for uav in holders if uav != victim)
    wait_until(lambda: seen.assignments[survivor].epoch == 1, 30.0, f"UAV {survivor} at epoch 1")
    assert seen.assignments[survivor].digest == replanned.digest  # the same re-plan

    status, out, err = finish(
        ground_cli(ground.router, "mission", "--until-reached", str(REACH_TIMEOUT_S), "--json"),
        REACH_TIMEOUT_S + 60,
    )
    report = json.loads(out)
    states = {s["index"]: s for s in report["target_states"]}
    assert states[orphan] == {"index": orphan, "state": "reached", "uav": idle}, err
    assert states[holders[survivor]]["state"] == "reached"
    assert report["epoch"] == 1 and report["lost"] == [victim]
    assert status == 0, err
    target = ring_targets(2, seed=7)[orphan]
    assert seen.closest_approach(idle, target.lat, target.lon) <= 75.0
