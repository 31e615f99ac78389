"""The mission changed in flight: `add-targets` and `remove-targets` from the ground's
commands against three real onboards in memory (tests/support/memory_world.py). Each
change is acknowledged by every UAV with a plan of its revision: one plan, an added
target in exactly one queue, a removed one in none. Flying it to the end is
tests/ground/test_mission_change_e2e.py."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from fleet.mission.key_space import KeySpace
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from ground.mission_change_command import (
    AddOptions,
    RemoveOptions,
    run_add_targets,
    run_remove_targets,
)
from ground.mission_commands import MissionOptions, run_mission
from ground.send_command import SendOptions, run_send_targets
from tests.support.agreement import AssignmentsHeard
from tests.support.memory_world import memory_fleet, ring_file
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
TARGETS = ring_targets(6, seed=23)
FIRST, LATER = TARGETS[:4], TARGETS[4:]


def reached(bus: Bus, mission: int) -> set[int]:
    """The targets `ground-cli mission` shows reached."""
    out = io.StringIO()
    run_mission(bus, MissionOptions(mission=mission, json=True), out)
    states = json.loads(out.getvalue())["target_states"]
    return {s["index"] for s in states if s["state"] == "reached"}


def test_targets_added_then_removed_in_flight_are_acknowledged_and_re_planned(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Flown slower than the wall clock: at ten times its pace, the changes took long
    # enough on a loaded machine for target 1 to be reached before its removal.
    with memory_fleet(ring_file(tmp_path, 3), speedup=0.2) as fleet:
        team = tuple(fleet.ids)
        bus = fleet.bus()
        seen = AssignmentsHeard(bus, SPACE)
        sent = SendOptions(targets=FIRST, team=team, wait=True, json=True)
        assert run_send_targets(bus, sent, io.StringIO()) == 0
        wait_until(lambda: set(team) <= set(seen.latest()), 30.0, "every commitment")
        mission = seen.latest()[team[0]].mission

        out = io.StringIO()
        # A bound on a loaded machine, not a budget: the command returns on the last ack.
        add = AddOptions(targets=LATER, mission=mission, json=True, timeout=60.0)
        assert run_add_targets(bus, add, out) == ExitCode.OK, capsys.readouterr().err
        added = json.loads(out.getvalue())
        assert (added["revision"], added["added"]) == (1, [4, 5])
        assert sorted(added["acknowledged"]) == sorted(team)
        queued = [t for q in added["queues"].values() for t in q]
        # Each target not reached yet in exactly one queue (a re-plan solves what is left).
        assert len(queued) == len(set(queued)) and {4, 5} <= set(queued)
        assert set(queued) | reached(bus, mission) == {0, 1, 2, 3, 4, 5}

        out = io.StringIO()
        remove = RemoveOptions(indexes=(1,), mission=mission, json=True, timeout=60.0)
        assert run_remove_targets(bus, remove, out) == ExitCode.OK, capsys.readouterr().err
        removed = json.loads(out.getvalue())
        assert (removed["revision"], removed["removed"]) == (2, [1])
        queued = [t for q in removed["queues"].values() for t in q]
        assert len(queued) == len(set(queued)) and 1 not in queued
        assert set(queued) | reached(bus, mission) == {0, 2, 3, 4, 5}
        # The change's acknowledgements may come from a fetch of each UAV's commitment,
        # ahead of the commitment's own publication: wait for every UAV's to be heard.
        wait_until(
            lambda: {r.revision for u, r in seen.latest().items() if u in team} == {2},
            30.0,
            "every UAV's revision 2 heard",
        )
        latest = seen.latest()
        assert len({latest[uav].digest for uav in team}) == 1  # one plan

        # The same index again, or one the mission does not have: nothing sent.
        again = RemoveOptions(indexes=(1,), mission=mission)
        assert run_remove_targets(bus, again, io.StringIO()) == ExitCode.FAILED
        assert "removed already" in capsys.readouterr().err
        beyond = RemoveOptions(indexes=(9,), mission=mission)
        assert run_remove_targets(bus, beyond, io.StringIO()) == ExitCode.FAILED
        assert "not one of" in capsys.readouterr().err
        assert {seen.latest()[uav].revision for uav in team} == {2}

        out = io.StringIO()
        run_mission(bus, MissionOptions(mission=mission, json=True), out)
        states = {s["index"]: s["state"] for s in json.loads(out.getvalue())["target_states"]}
        assert states[1] == "removed" and len(states) == 6
