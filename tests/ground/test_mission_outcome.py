"""What the ground concludes about a mission: success, target states, re-plan epochs."""

from __future__ import annotations

import msgspec

from fleet.mission.messages import (
    AssignmentReport,
    MissionProgress,
    Target,
    TargetOutcome,
    UavResult,
    UavState,
)
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


def _two_committed(mission: int = 4) -> MissionOutcome:
    """UAVs 101 and 102 agreed: 101 holds target 0, 102 target 1."""
    pairs = {101: 0, 102: 1}
    outcome = MissionOutcome(mission=mission, team=(101, 102), targets=TARGETS[:2])
    outcome.assignments = {
        uav: AssignmentReport(mission, uav, target, pairs, (), (101, 102), "d")
        for uav, target in pairs.items()
    }
    return outcome


def _state(uav: int, phase: Phase, mission: int, reason: str | None = None) -> UavState:
    progress = MissionProgress(mission=mission, phase=phase, targets=2)
    return UavState(uav, True, 1.0, None, None, None, progress, phase=phase, reason=reason)


def test_a_target_whose_holder_aborted_reads_aborted_and_the_mission_fails() -> None:
    outcome = _two_committed()
    assert outcome.succeeded
    outcome.note_state(_state(101, Phase.ABORTED, 4))
    outcome.note_state(_state(102, Phase.FLYING, 4))
    states = {s["index"]: s for s in outcome.target_states()}
    assert states[0] == {"index": 0, "state": "aborted", "uav": 101, "reason": "UAV 101 aborted"}
    assert states[1] == {"index": 1, "state": "assigned", "uav": 102}
    assert outcome.to_json()["success"] is False
    assert "  target 0: aborted (UAV 101): UAV 101 aborted" in summary_lines(outcome)


def test_a_holder_s_failed_or_preempted_outcome_names_the_phase_and_reason() -> None:
    outcome = _two_committed()
    outcome.outcomes = {
        101: TargetOutcome(4, 101, 0, Phase.FAILED, "no echo"),
        102: TargetOutcome(4, 102, 1, Phase.PREEMPTED, "left the route"),
    }
    states = outcome.target_states()
    assert [(s["state"], s["uav"], s["reason"]) for s in states] == [
        ("failed", 101, "no echo"),
        ("preempted", 102, "left the route"),
    ]
    assert not outcome.succeeded


def test_an_aborted_target_reached_by_its_holder_stays_reached_and_a_success() -> None:
    outcome = _two_committed()
    outcome.outcomes = {
        101: TargetOutcome(4, 101, 0, Phase.REACHED),
        102: TargetOutcome(4, 102, 1, Phase.REACHED),
    }
    outcome.note_state(_state(101, Phase.ABORTED, 4))
    assert [s["state"] for s in outcome.target_states()] == ["reached", "reached"]
    assert outcome.succeeded


def test_a_phase_of_a_later_mission_says_nothing_about_this_one() -> None:
    outcome = _two_committed()
    outcome.note_state(_state(101, Phase.ABORTED, 5))
    assert outcome.target_states()[0]["state"] == "assigned"


def test_a_target_no_uav_has_a_route_to_is_unserved_with_that_reason() -> None:
    targets = TARGETS[:2]
    outcome = MissionOutcome(mission=4, team=(74, 112), targets=targets)
    outcome.results = {
        74: UavResult(4, 74, (30.0, None)),
        112: UavResult(4, 112, (40.0, None)),
    }
    report = AssignmentReport(4, 74, 0, {74: 0}, (1,), (74, 112), "d")
    outcome.assignments = {
        74: report,
        112: AssignmentReport(4, 112, None, {74: 0}, (1,), (74, 112), "d"),
    }
    states = {s["index"]: s for s in outcome.target_states()}
    assert states[1]["state"] == "unserved"
    assert states[1]["reason"] == "no route around the no-fly zones reaches it"
    assert outcome.succeeded  # the team did what it could


def test_queued_targets_have_a_holder_a_place_and_a_predicted_arrival() -> None:
    """One UAV queues targets 0 then 2, its teammate 1; target 2 reached by the
    teammate (a re-plan) is reached whoever's queue it was in; the summary tells queues."""
    queues = {101: (0, 2), 102: (1,)}
    arrivals = {101: (40.0, 130.0), 102: (55.0,)}
    targets = (*TARGETS[:2], Target(35.73, -120.75, 600.0))
    outcome = MissionOutcome(mission=6, team=(101, 102), targets=targets)
    outcome.assignments = {
        uav: AssignmentReport(
            6, uav, queues[uav][0], {101: 0, 102: 1}, (), (101, 102), "d",
            eta_s=arrivals[uav][0], queues=queues, arrivals=arrivals,
        )
        for uav in (101, 102)
    }  # fmt: skip
    states = {s["index"]: s for s in outcome.target_states()}
    assert states[2] == {"index": 2, "state": "assigned", "uav": 101, "place": 2, "eta_s": 130.0}
    assert outcome.unassigned() == [] and outcome.to_json()["queues"] == {"101": [0, 2], "102": [1]}
    assert any("UAV 101: target 0 ETA 40 s, then 2" in line for line in summary_lines(outcome))
    # A teammate's word that a lost UAV reached a target is a hint, not a fact: it is
    # reached once that UAV's own outcome (relayed by a teammate) says so.
    outcome.outcomes = {102: TargetOutcome(6, 102, 1, Phase.REACHED, reached={0: 101, 1: 102})}
    assert outcome.reached_by() == {1: 102}
    outcome.outcomes[101] = TargetOutcome(6, 101, 0, Phase.REACHED, reached={0: 101})
    assert outcome.reached_by() == {0: 101, 1: 102}


def test_mission_shows_who_left_and_came_back_and_every_target_flown_twice() -> None:
    team = (101, 102, 103)

    def report(uav: int) -> AssignmentReport:
        return AssignmentReport(
            1, uav, None, {101: 0, 102: 1, 103: 2}, (), team, "d", epoch=4,
            released=(102,), left={102: 2, 103: 1}, back={102: 1, 103: 1}, revision=1,
        )  # fmt: skip

    outcome = MissionOutcome(mission=1, team=team, targets=TARGETS)
    outcome.assignments = {uav: report(uav) for uav in team}
    outcome.outcomes = {
        101: TargetOutcome(1, 101, 0, Phase.REACHED, reached={0: 101, 1: 103}),
        102: TargetOutcome(1, 102, 1, Phase.LINK_LOST, "no telemetry for 60 s"),
        103: TargetOutcome(1, 103, 0, Phase.REACHED, reached={1: 103}),  # 0 again, by 103
    }
    assert outcome.flown_twice() == {0: [101, 103]}
    rows = {row["uav"]: row for row in outcome.membership()}
    assert rows[102] == {
        "uav": 102, "left": 2, "back": 1, "out": True, "why": "no telemetry for 60 s"
    }  # fmt: skip
    assert rows[103]["out"] is False and rows[103]["why"] == "liveliness lost"
    # A UAV the first plan was built without (a side re-based onto it after a heal) is
    # counted out once and back once: it joined, its liveliness never went.
    joined = msgspec.structs.replace(report(101), left={104: 1}, back={104: 1}, released=())
    outcome.assignments[101] = joined
    assert outcome.membership() == [
        {"uav": 104, "left": 1, "back": 1, "out": False,
         "why": "counted in: the first plan was built without it"}
    ]  # fmt: skip
    outcome.assignments[101] = report(101)
    report_json = outcome.to_json()
    assert report_json["flown_twice"] == {"0": [101, 103]} and report_json["revision"] == 1
    lines = summary_lines(outcome)
    assert "  target 0: FLOWN TWICE, by UAVs 101, 103" in lines
    assert any("UAV 102: left 2x (no telemetry for 60 s), came back 1x: out" in s for s in lines)
    assert "  re-planned: epoch 4 (mission revision 1)" in lines


def test_mission_shows_who_asked_for_a_re_plan_in_the_air_of_now() -> None:
    team = (101, 102)
    report = AssignmentReport(
        1, 101, 0, {101: 0, 102: 1}, (), team, "d", epoch=2, asked={101: 1, 102: 1}
    )
    outcome = MissionOutcome(mission=1, team=team, targets=TARGETS)
    outcome.assignments = {101: report, 102: msgspec.structs.replace(report, uav=102, target=1)}
    assert outcome.asked() == {101: 1, 102: 1} and outcome.membership() == []
    assert outcome.to_json()["asked"] == {"101": 1, "102": 1}
    assert "  re-planned in the air of now: asked by UAV 101 1x, UAV 102 1x" in summary_lines(
        outcome
    )


def test_an_ask_is_shown_from_the_askers_own_report_not_from_a_teammates() -> None:
    """101's report says 102 asked three times; 102's own says once, 101 never asked:
    the ground shows what each asker said of itself, as the UAVs believe it."""
    team = (101, 102)
    claims = AssignmentReport(1, 101, 0, {101: 0, 102: 1}, (), team, "d", epoch=3, asked={102: 3})
    own = msgspec.structs.replace(claims, uav=102, target=1, epoch=1, asked={102: 1})
    outcome = MissionOutcome(mission=1, team=team, targets=TARGETS)
    outcome.assignments = {101: claims, 102: own}
    assert outcome.asked() == {102: 1}
