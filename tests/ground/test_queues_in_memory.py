"""Task queues by objective: `send-targets --wait --objective` from the ground's command
against three real onboards in memory (tests/support/memory_world.py): every UAV agrees
on one plan (one digest, the same queues, every target in exactly one), and the JSON
tells each target its holder, its place in that queue and its arrival. Flying the
queues to the end is tests/ground/test_queues_e2e.py."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport
from fleet.mission.objective import Objective
from ground.send_command import SendOptions, run_send_targets
from tests.support.agreement import AssignmentsHeard, assert_one_plan
from tests.support.memory_world import MemoryFleet, memory_fleet, ring_file
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()
#: The ring scenario's first UAV: the one that proposes.
_FIRST = 101
TARGETS = ring_targets(8, seed=23)


def send_and_commit(
    fleet: MemoryFleet, **options: Any
) -> tuple[dict[str, Any], dict[int, AssignmentReport]]:
    """`send-targets --wait --json` of TARGETS to the whole fleet, with `options`: its
    JSON report, and each UAV's commitment once every UAV has committed."""
    team = fleet.ids
    seen = AssignmentsHeard(fleet.bus(), SPACE)
    out = io.StringIO()
    sent = SendOptions(targets=TARGETS, team=team, wait=True, json=True, **options)
    assert run_send_targets(fleet.bus(), sent, out) == 0
    report = json.loads(out.getvalue())
    wait_until(lambda: set(team) <= set(seen.latest()), 30.0, "every commitment")
    latest = seen.latest()
    return report, {uav: latest[uav] for uav in team}


def assert_verdict(said: dict[str, Any], reports: dict[int, AssignmentReport]) -> str:
    """A proposal's verdict in the JSON (`said`) is what every UAV's commitment says: the
    team adopted it, or kept the baseline; the verdict."""
    verdict: str = said["verdict"]
    assert verdict in ("adopted", "baseline"), said
    digests = {report.digest for report in reports.values()}
    assert said[f"{verdict}_by"] == sorted(reports) and digests == {said[f"{verdict}_digest"]}
    return verdict


@pytest.mark.parametrize("objective", [Objective.MIN_SUM, Objective.MIN_MAX])
def test_every_uav_agrees_on_the_plan_of_each_objective(
    tmp_path: Path, objective: Objective
) -> None:
    with memory_fleet(ring_file(tmp_path, 3)) as fleet:
        report, reports = send_and_commit(fleet, objective=objective)
    assert report["agreed"] is True and report["complete"] is True
    assert_one_plan(report, reports, len(TARGETS))
    assert {str(r.objective) for r in reports.values()} == {str(objective)}


def test_send_targets_propose_says_whether_the_team_adopted_the_proposal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`--propose --wait --json`: the verdict is what every UAV's reported digest says."""
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    with memory_fleet(ring_file(tmp_path, 3)) as fleet:
        report, reports = send_and_commit(fleet, objective=Objective.MIN_MAX, propose=True)
    verdict = assert_verdict(report["proposal"], reports)
    assert f"the ground's proposal: {'adopted by' if verdict == 'adopted' else 'not'}" in (
        capsys.readouterr().err
    )


def test_a_uav_proposes_and_every_uav_adopts_one_plan(tmp_path: Path) -> None:
    """`send-targets --proposers U` to a fleet whose UAV U solves on board (`--propose`):
    U's proposal, signed as U on its own key, is verified by every UAV; all report one
    digest, and the ground reads from it whether they adopted U's plan."""
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    with memory_fleet(ring_file(tmp_path, 3), proposers=frozenset({_FIRST})) as fleet:
        assert _FIRST in fleet.ids
        report, reports = send_and_commit(fleet, objective=Objective.MIN_MAX, proposers=(_FIRST,))
    assert_verdict(report["uav_proposals"][str(_FIRST)], reports)
