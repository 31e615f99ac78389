"""Task queues by objective: `send-targets --wait --objective` from the ground's command
against three real onboards in memory (tests/support/memory_world.py): every UAV agrees
on one plan (one digest, the same queues, every target in exactly one), and the JSON
tells each target its holder, its place in that queue and its arrival. Flying the
queues to the end is tests/ground/test_queues_e2e.py."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.objective import Objective
from ground.send_command import SendOptions, run_send_targets
from tests.support.agreement import AssignmentsHeard, assert_one_plan
from tests.support.memory_world import memory_fleet, ring_file
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
#: The ring scenario's first UAV: the one that proposes.
_FIRST = 101
TARGETS = ring_targets(8, seed=23)


@pytest.mark.parametrize("objective", [Objective.MIN_SUM, Objective.MIN_MAX])
def test_every_uav_agrees_on_the_plan_of_each_objective(
    tmp_path: Path, objective: Objective
) -> None:
    with memory_fleet(ring_file(tmp_path, 3)) as fleet:
        team = list(fleet.ids)
        seen = AssignmentsHeard(fleet.bus(), SPACE)
        out = io.StringIO()
        options = SendOptions(
            targets=TARGETS, team=tuple(team), wait=True, json=True, objective=objective
        )
        assert run_send_targets(fleet.bus(), options, out) == 0
        report = json.loads(out.getvalue())
        assert report["agreed"] is True and report["complete"] is True
        wait_until(lambda: set(team) <= set(seen.latest()), 30.0, "every commitment")
        latest = seen.latest()
        reports = {uav: latest[uav] for uav in team}
    assert_one_plan(report, reports, len(TARGETS))
    assert {str(r.objective) for r in reports.values()} == {str(objective)}


def test_send_targets_propose_says_whether_the_team_adopted_the_proposal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--propose --wait --json`: the verdict is what every UAV's reported digest says."""
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    with memory_fleet(ring_file(tmp_path, 3)) as fleet:
        team = sorted(fleet.ids)
        seen = AssignmentsHeard(fleet.bus(), SPACE)
        out = io.StringIO()
        options = SendOptions(
            targets=TARGETS,
            team=tuple(team),
            wait=True,
            json=True,
            objective=Objective.MIN_MAX,
            propose=True,
        )
        assert run_send_targets(fleet.bus(), options, out) == 0
        said = json.loads(out.getvalue())["proposal"]
        wait_until(lambda: set(team) <= set(seen.latest()), 30.0, "every commitment")
        digests = {seen.latest()[uav].digest for uav in team}
    verdict = said["verdict"]
    assert verdict in ("adopted", "baseline"), said
    assert said[f"{verdict}_by"] == team and digests == {said[f"{verdict}_digest"]}
    assert f"the ground's proposal: {'adopted by' if verdict == 'adopted' else 'not'}" in (
        capsys.readouterr().err
    )


def test_a_uav_proposes_and_every_uav_adopts_one_plan(tmp_path: Path) -> None:
    """`send-targets --proposers U` to a fleet whose UAV U solves on board (`--propose`):
    U's proposal, signed as U on its own key, is verified by every UAV; all report one
    digest, and the ground reads from it whether they adopted U's plan."""
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    with memory_fleet(ring_file(tmp_path, 3), proposers=frozenset({_FIRST})) as fleet:
        team = sorted(fleet.ids)
        assert _FIRST in team
        seen = AssignmentsHeard(fleet.bus(), SPACE)
        out = io.StringIO()
        options = SendOptions(
            targets=TARGETS,
            team=tuple(team),
            wait=True,
            json=True,
            objective=Objective.MIN_MAX,
            proposers=(_FIRST,),
        )
        assert run_send_targets(fleet.bus(), options, out) == 0
        said = json.loads(out.getvalue())["uav_proposals"][str(_FIRST)]
        wait_until(lambda: set(team) <= set(seen.latest()), 30.0, "every commitment")
        digests = {seen.latest()[uav].digest for uav in team}
    verdict = said["verdict"]
    assert verdict in ("adopted", "baseline"), said
    assert said[f"{verdict}_by"] == team and digests == {said[f"{verdict}_digest"]}
