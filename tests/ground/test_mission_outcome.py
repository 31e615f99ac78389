"""What the ground concludes about a mission: success, target states, re-plan epochs."""

from __future__ import annotations

from fleet.mission.messages import AssignmentReport, TargetOutcome
from fleet.mission.phase import Phase
from ground.mission_outcome import MissionOutcome
from ground.mission_summary import summary_lines
from tests.ground.mission_samples import (
    TARGETS,
)


def test_a_superseded_mission_is_no_success_even_when_agreed() -> None:
    outcome = MissionOutcome(mission=3, team=(), targets=TARGETS)
    assert outcome.to_json()["superseded_by"] is None
    outcome.superseded_by = 5
    report = outcome.to_json()
    assert report["superseded_by"] == 5
    assert report["success"] is False


def test_the_summary_says_superseded() -> None:
    outcome = MissionOutcome(mission=2, team=(7,), targets=TARGETS, superseded_by=3)
    assert "  SUPERSEDED by mission 3: the team no longer flies mission 2" in summary_lines(outcome)


def test_after_a_re_plan_a_target_belongs_to_its_latest_epoch_holder() -> None:
    def report(uav: int, target: int | None, epoch: int) -> AssignmentReport:
        pairs = {101: 0, 102: 1} if epoch == 0 else {102: 1, 103: 0}
        released = () if epoch == 0 else (101,)
        return AssignmentReport(
            1, uav, target, pairs, (), (101, 102, 103), "d", epoch=epoch, released=released
        )

    outcome = MissionOutcome(mission=1, team=(101, 102, 103), targets=TARGETS)
    outcome.assignments = {101: report(101, 0, 0), 102: report(102, 1, 1), 103: report(103, 0, 1)}
    outcome.lost = {101}
    assert outcome.epoch == 1
    assert outcome.holders() == {0: 103, 1: 102}
    states = {s["index"]: s for s in outcome.target_states()}
    assert states[0] == {"index": 0, "state": "assigned", "uav": 103}
    outcome.outcomes = {103: TargetOutcome(1, 103, 0, Phase.REACHED)}
    assert outcome.target_states()[0] == {"index": 0, "state": "reached", "uav": 103}
    assert outcome.succeeded
