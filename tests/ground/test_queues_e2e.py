"""Task queues end to end: real simulator, onboards, router and `ground-cli`.

Three UAVs and eight targets: every target reached, and `mission --until-reached` says
so; the same with a holder SIGKILLed after its first target, mid-queue, its queue going
to the others; `min-sum` and `min-max` each agreed by every UAV is test_queues_in_memory.py."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.mission.phase import Phase
from tests.conftest import Ground
from tests.ground.test_truth import targets_file
from tests.onboard.test_multi_uav import start_ring
from tests.support.agreement import assert_one_plan
from tests.support.ground_cli import finish_ground_cli, start_ground_cli
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

SPEEDUP = 10.0
TARGETS = ring_targets(8, seed=23)
#: Simulated flight of three queues of about three targets each, at SPEEDUP: ~1 minute;
#: generous for a loaded machine.
REACH_TIMEOUT_S = 300.0
#: How close (m) telemetry must have put a UAV to a target it is said to have reached.
CLOSE_M = 75.0


def _queues_of_three(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> tuple[list[int], dict[int, tuple[int, ...]]]:
    """Three UAVs on a ring sent the eight targets (`send-targets --wait`), and every one
    committed to one plan: the team and the plan's queues."""
    team = start_ring(fleet, ground, tmp_path, 3, SPEEDUP, telemetry_hz=5.0)
    path = targets_file(tmp_path, TARGETS)
    status, out, err = finish_ground_cli(
        start_ground_cli(
            "send-targets",
            str(path),
            "--team",
            ",".join(map(str, team)),
            "--wait",
            "--json",
            connect=ground.router,
        ),
        120,
    )
    assert status == 0, err
    report = json.loads(out)
    assert report["agreed"] is True and report["complete"] is True, err
    seen = ground.seen
    wait_until(lambda: set(team) <= set(seen.assignments), 30.0, "every commitment")
    reports = {uav: seen.assignments[uav] for uav in team}
    assert_one_plan(report, reports, len(TARGETS))
    return team, reports[team[0]].queues


def _until_reached(ground: Ground) -> dict[str, object]:
    status, out, err = finish_ground_cli(
        start_ground_cli(
            "mission", "--until-reached", str(REACH_TIMEOUT_S), "--json", connect=ground.router
        ),
        REACH_TIMEOUT_S + 60,
    )
    report: dict[str, object] = json.loads(out)
    assert status == 0, (err, report["target_states"])
    return report


def _assert_each_reached_where_it_is(ground: Ground, report: dict[str, object]) -> dict[int, int]:
    states = report["target_states"]
    assert isinstance(states, list)
    by = {s["index"]: s["uav"] for s in states if s["state"] == "reached"}
    assert sorted(by) == list(range(len(TARGETS))), states
    for index, uav in by.items():
        target = TARGETS[index]
        assert ground.seen.closest_approach(uav, target.lat, target.lon) <= CLOSE_M
    return by


def test_three_uavs_reach_all_eight_targets_through_their_queues(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    _, queues = _queues_of_three(fleet, ground, tmp_path)
    assert max(len(q) for q in queues.values()) >= 2  # more targets than UAVs: queues
    report = _until_reached(ground)
    by = _assert_each_reached_where_it_is(ground, report)
    # Each target reached by the UAV whose queue holds it, in its queue's order.
    for uav, queue in queues.items():
        assert all(by[t] == uav for t in queue)
        order = [o.target for o in ground.seen.outcomes_of(uav) if o.phase == Phase.REACHED]
        assert order == list(queue)
    assert report["success"] is True


def test_a_holder_killed_mid_queue_hands_its_queue_on_and_every_target_is_reached(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    team, queues = _queues_of_three(fleet, ground, tmp_path)
    victim = max(queues, key=lambda uav: (len(queues[uav]), uav))
    assert len(queues[victim]) >= 2
    seen = ground.seen
    wait_until(
        lambda: any(o.phase == Phase.REACHED for o in seen.outcomes_of(victim)),
        REACH_TIMEOUT_S,
        f"UAV {victim} reaching its first target",
    )
    child = fleet.onboard_child(victim)
    child.process.kill()  # SIGKILL, mid-queue: liveliness goes with its connection
    child.process.wait(10)
    done = {o.target for o in seen.outcomes_of(victim) if o.phase == Phase.REACHED}
    assert done and set(queues[victim]) - done, "killed with targets left in its queue"
    survivors = [uav for uav in team if uav != victim]
    wait_until(
        lambda: all(seen.assignments[uav].epoch == 1 for uav in survivors),
        30.0,
        "both survivors re-planning epoch 1",
    )
    first, second = (seen.assignments[uav] for uav in survivors)
    assert first.digest == second.digest and first.queues == second.queues
    assert first.released == (victim,) and first.unassigned == ()
    # What was left was solved again from the survivors' fresh times: every target of
    # the victim's queue it had not reached is in exactly one survivor's queue.
    assert first.basis is not None
    queued = [t for q in first.queues.values() for t in q]
    assert len(queued) == len(set(queued)) and set(first.queues) <= set(survivors)
    assert set(queues[victim]) - done <= set(queued)

    report = _until_reached(ground)
    by = _assert_each_reached_where_it_is(ground, report)
    assert {t for t, uav in by.items() if uav == victim} == done
    assert report["epoch"] == 1 and report["lost"] == [victim]


# Every UAV agreeing on the plan of each objective: tests/ground/test_queues_in_memory.py.
