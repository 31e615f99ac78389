"""What a recording says about a mission, the report and the figure (from made-up messages)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import msgspec
import pytest

from fleet.mission.messages import (
    AssignmentReport,
    LinkHealth,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    NoFlyZone,
    StatusText,
    Target,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.piccolo.track import Track
from fleet.recording import channels
from fleet.recording.mission_log import Timeline, build_timeline
from fleet.recording.plot import PlotError, arrival_bars, mission_window, panels, parse_at, render
from fleet.recording.reader import RecordedMessage
from fleet.recording.report import report_json, report_lines

NS = 1_000_000_000
TARGETS = (Target(35.72, -120.76, 600.0), Target(35.70, -120.74, 600.0))
TEAM = (1, 2)


def message(t: float, key: str, value: msgspec.Struct) -> RecordedMessage:
    spec = channels.channel_for(key)
    return RecordedMessage(
        key,
        spec.pattern,
        spec.schema_name,
        round(t * NS),
        round(t * NS),
        msgspec.json.encode(value),
    )


def telemetry(t: float, uav: int, lat: float, lon: float, clock_s: float) -> RecordedMessage:
    gps = GpsBlock(lat=lat, lon=lon, alt=600.0, vel_north=0.0, vel_east=20.0, vel_down=0.0)
    return message(t, f"fleet/uav/{uav}/telemetry", Telemetry(round(clock_s * 1000), gps=gps))


def report(uav: int, target: int, eta: float, digest: str = "d1") -> AssignmentReport:
    return AssignmentReport(
        mission=5,
        uav=uav,
        target=target,
        pairs={1: 0, 2: 1},
        unassigned=(),
        team=TEAM,
        digest=digest,
        eta_s=eta,
    )


def mission_messages(digest_2: str = "d1") -> list[RecordedMessage]:
    """UAV 1 flies to target 0 and reaches it; UAV 2 commits to target 1, never arrives."""
    found = [
        # Aircraft clocks run 10x the wall clock (a speedup 10 simulation).
        *(telemetry(t, 1, 35.72, -120.80 + 0.004 * t, 100 + 10 * t) for t in range(0, 12)),
        *(telemetry(t, 2, 35.68, -120.70 - 0.001 * t, 500 + 10 * t) for t in range(0, 12)),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, TEAM, TARGETS)),
        message(1.5, "fleet/mission/5/result/1", UavResult(5, 1, (40.0, 90.0))),
        message(1.6, "fleet/mission/5/result/2", UavResult(5, 2, (80.0, 30.0))),
        message(2.0, "fleet/mission/5/assignment/1", report(1, 0, 45.0)),
        message(2.5, "fleet/mission/5/assignment/2", report(2, 1, 30.0, digest_2)),
        message(3.0, "fleet/uav/1/track", Track(90)),
        message(3.2, "fleet/uav/2/track", Track(90)),
        message(6.0, "fleet/uav/2/link", LinkHealth(False, True, 3, {}, None)),
        message(6.5, "fleet/uav/2/link", LinkHealth(False, True, 3, {}, None)),
        message(7.0, "fleet/uav/1/track", Track(0)),
        message(
            7.1, "fleet/uav/1/status", StatusText("reached target 0", StatusKind.REACHED, 5, 0)
        ),
    ]
    return found


def test_the_mission_events_come_from_what_was_heard() -> None:
    timeline = build_timeline(mission_messages())
    (log,) = timeline.missions
    assert (log.mission, log.team, log.sent) == (5, TEAM, 1.0)
    assert log.committed == {1: 2.0, 2: 2.5} and log.all_committed == 2.5
    assert log.course_change == {1: 3.0, 2: 3.2}
    assert log.reached == {1: 7.0} and log.reached_how == {1: "track"}
    assert log.resumed == {1: 7.0}
    # Flown on the aircraft's clock: commit at wall 2 s (aircraft 120 s), reach at
    # wall 7 s (aircraft 170 s).
    assert log.flown_s == {1: pytest.approx(50.0)}
    assert log.agreed
    assert list(log.events()) == ["sent", "committed", "course change", "reached", "resumed"]
    faults = [what for _, what in log.faults]
    assert faults == ["UAV 2: program link down", "UAV 2 not seen to reach its target"]


def raw(t: float, key: str, json: bytes) -> RecordedMessage:
    spec = channels.channel_for(key)
    return RecordedMessage(key, spec.pattern, spec.schema_name, round(t * NS), round(t * NS), json)


def test_arrival_and_faults_are_read_from_the_status_kind_not_its_text() -> None:
    said = [
        message(3.5, "fleet/uav/2/status", StatusText("target reached?", StatusKind.INFO)),
        message(
            4.0,
            "fleet/uav/2/status",
            StatusText("warning: target not reached: x", StatusKind.NOT_REACHED, 5, 1),
        ),
        message(5.0, "fleet/uav/1/status", StatusText("arrived", StatusKind.REACHED, 5, 0)),
    ]
    (log,) = build_timeline([*mission_messages(), *said]).missions
    assert log.reached == {1: 5.0} and log.reached_how == {1: "status"}
    assert "UAV 2: warning: target not reached: x" in [what for _, what in log.faults]


def test_a_status_recorded_before_status_kinds_still_reads() -> None:
    """No `kind`: its text says an arrival, the severity it carried says a fault."""
    said = [
        raw(4.0, "fleet/uav/2/status", b'{"text": "GPS degraded", "severity": "warning"}'),
        raw(5.0, "fleet/uav/1/status", b'{"text": "reached target 0", "severity": "info"}'),
    ]
    (log,) = build_timeline([*mission_messages(), *said]).missions
    assert log.reached == {1: 5.0} and log.reached_how == {1: "status"}
    assert "UAV 2: GPS degraded" in [what for _, what in log.faults]


def test_disagreeing_digests_are_a_fault() -> None:
    (log,) = build_timeline(mission_messages(digest_2="other")).missions
    assert not log.agreed
    assert "the team's assignments disagree" in [what for _, what in log.faults]


def test_undecodable_messages_are_counted_not_fatal() -> None:
    bad = RecordedMessage("fleet/mission/5/targets", "", "", 0, 0, b'{"mission": "x"}')
    timeline = build_timeline([bad, *mission_messages()])
    assert timeline.undecodable == 1 and len(timeline.missions) == 1


def test_the_report_per_mission() -> None:
    timeline = build_timeline(mission_messages())
    data = report_json(timeline)
    (mission,) = data["missions"]
    assert mission["assignment"] == {"1": 0, "2": 1}
    assert mission["predicted_s"] == {"1": 45.0, "2": 30.0}
    assert mission["flown_s"] == {"1": 50.0, "2": None}
    assert mission["send_to_commit_s"] == 1.5
    assert mission["approach_times_s"]["2"] == [80.0, 30.0]
    text = "\n".join(report_lines(timeline))
    assert "UAV 1: target 0; approach 40.0, 90.0; predicted 45.0 s, flown 50.0 s" in text
    assert "UAV 2: target 1" in text and "NOT reached" in text
    assert "send -> commit: 1.50 s" in text


def test_an_aborted_team_s_turn_back_to_course_is_no_arrival() -> None:
    """The abort, not an arrival, took UAV 1 off its target waypoint: before, the
    report said 'flown 50.0 s (track)'."""
    said = [message(6.8, "fleet/mission/5/abort", MissionAbort(5))]
    unsaid = [m for m in mission_messages() if not m.topic.endswith("/status")]
    timeline = build_timeline([*unsaid, *said])
    (log,) = timeline.missions
    assert log.reached == {} and log.flown_s == {}
    assert log.ended == {1: (6.8, "aborted"), 2: (6.8, "aborted")}
    faults = [what for _, what in log.faults]
    assert "mission 5 aborted by the ground" in faults
    assert "UAV 1 aborted: its target not reached" in faults
    (mission,) = report_json(timeline)["missions"]
    assert mission["flown_s"] == {"1": None, "2": None}
    assert mission["reached"] == {"1": False, "2": False}
    assert mission["ended"]["1"] == {"at_s": 6.8, "how": "aborted"}
    text = "\n".join(report_lines(timeline))
    assert "UAV 1: target 0; approach 40.0, 90.0; predicted 45.0 s, ABORTED at 6.8 s" in text
    assert "flown" not in text.split("agreed")[0].split("UAV 1:")[1]


def test_a_uav_aborted_alone_or_preempted_is_not_reached_and_its_teammate_is() -> None:
    progress = MissionProgress(5, Phase.PREEMPTED, 2)
    preempted = UavState(2, True, 1.0, 0, None, None, progress, phase=Phase.PREEMPTED)
    alone = [message(5.0, "fleet/mission/5/abort", MissionAbort(5, uav=2))]
    (log,) = build_timeline([*mission_messages(), *alone]).missions
    assert log.reached == {1: 7.0} and 1 in log.flown_s
    assert log.ended == {2: (5.0, "aborted")} and 2 not in log.flown_s
    assert "mission 5 aborted by the ground for UAV 2 alone" in [w for _, w in log.faults]
    back = [message(6.0, "fleet/uav/2/track", Track(0))]  # off the target: not arrived
    told = [message(6.1, "fleet/uav/2/state", preempted)]
    (log,) = build_timeline([*mission_messages(), *back, *told]).missions
    assert log.ended == {2: (6.1, "preempted")} and 2 not in log.reached


def test_the_figure_is_a_png(tmp_path: Path) -> None:
    out = render(build_timeline(mission_messages()), tmp_path / "m.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    only = render(build_timeline(mission_messages()), tmp_path / "a.png", at=["sent", 4.0])
    assert only.stat().st_size > 0


def test_panels_asked_for_wrongly_say_why(tmp_path: Path) -> None:
    with pytest.raises(PlotError, match="neither an event"):
        parse_at("sent,lunch")
    assert parse_at("sent, 12.5") == ["sent", 12.5]
    timeline = build_timeline(mission_messages()[:30])  # no arrival yet
    with pytest.raises(PlotError, match="not in this mission"):
        render(timeline, tmp_path / "x.png", at=["reached"])
    with pytest.raises(PlotError, match="mission 9 is not in the recording"):
        render(timeline, tmp_path / "x.png", mission=9)


def test_the_mission_s_zones_are_read_and_drawn_under_the_tracks(tmp_path: Path) -> None:
    zone = NoFlyZone(
        ring=((35.71, -120.78), (35.71, -120.77), (35.715, -120.77), (35.715, -120.78)),
        name="town",
    )
    zoned = MissionTargets(5, TEAM, TARGETS, zones=(zone,))
    zoned_message = message(1.0, "fleet/mission/5/targets", zoned)
    messages = [
        zoned_message if m.topic == "fleet/mission/5/targets" else m for m in mission_messages()
    ]
    timeline = build_timeline(messages)
    assert timeline.missions[0].zones == (zone,)
    plain = render(build_timeline(mission_messages()), tmp_path / "plain.png", at=["sent"])
    with_zone = render(timeline, tmp_path / "zones.png", at=["sent"])
    assert with_zone.read_bytes() != plain.read_bytes()
    # A zone that is no polygon is an undecodable record, not a crash.
    bowtie = NoFlyZone(ring=((35.7, -120.7), (35.8, -120.6), (35.8, -120.7), (35.7, -120.6)))
    bad = message(1.0, "fleet/mission/6/targets", MissionTargets(6, TEAM, TARGETS, zones=(bowtie,)))
    assert build_timeline([bad]).undecodable == 1


def tour_of_two() -> Timeline:
    """UAV 1 queues targets 0 then 1, planned to arrive at 45 s and 120 s, and reaches
    them at 7 s and 12 s on its clock (each leg flown in 50 s of telemetry time)."""
    return build_timeline(tour_messages())


def tour_messages() -> list[RecordedMessage]:
    """`tour_of_two`'s recording."""
    tour = AssignmentReport(
        5, 1, 0, {1: 0}, (), (1,), "d1", eta_s=45.0, queues={1: (0, 1)}, arrivals={1: (45.0, 120.0)}
    )
    return [
        *(telemetry(t, 1, 35.72, -120.80 + 0.004 * t, 100 + 10 * t) for t in range(0, 14)),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, (1,), TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", tour),
        message(7.0, "fleet/mission/5/outcome/1", TargetOutcome(5, 1, 0, Phase.REACHED)),
        message(12.0, "fleet/mission/5/outcome/1", TargetOutcome(5, 1, 1, Phase.REACHED)),
    ]


def test_a_tour_s_legs_predicted_and_flown(tmp_path: Path) -> None:
    """UAV 1 queues targets 0 then 1: each leg's predicted time from the
    plan's arrivals, its flown time on the aircraft's clock between reached outcomes."""
    timeline = tour_of_two()
    (log,) = timeline.missions
    assert log.legs(1, timeline.tracks) == [
        {"target": 0, "predicted_s": 45.0, "flown_s": 50.0},
        {"target": 1, "predicted_s": 75.0, "flown_s": 50.0},
    ]
    mission = report_json(timeline)["missions"][0]
    assert mission["queues"] == {"1": [0, 1]} and len(mission["legs"]["1"]) == 2
    assert any(
        "UAV 1 tour: 0 (45.0 s predicted, 50.0 s flown), 1 (75.0 s predicted, 50.0 s flown)" in line
        for line in report_lines(timeline)
    )
    # The figure draws the tour (a dotted line in the UAV's colour) and stays a PNG.
    assert render(timeline, tmp_path / "tour.png").read_bytes()[:4] == b"\x89PNG"


def test_every_leg_off_by_more_than_10_percent_is_flagged() -> None:
    """Target 1's leg was predicted 75 s and flown in 50 s: +50 %, flagged in the text
    and the JSON; target 0's (45 s predicted, 50 s flown: -10 %) is not."""
    timeline = tour_of_two()
    legs = report_json(timeline)["missions"][0]["legs"]["1"]
    assert [(leg["off"], leg["error"]) for leg in legs] == [(False, -0.1), (True, 0.5)]
    lines = report_lines(timeline)
    assert any("1 (75.0 s predicted, 50.0 s flown) OFF by +50 %" in line for line in lines)
    assert any("1 leg(s) predicted off the time flown by more than 10%" in line for line in lines)


def test_each_leg_s_time_said_as_it_began_is_beside_the_plan_s() -> None:
    """UAV 1's state said 52 s for its leg to target 1 as it began it (the plan said
    75 s; it flew 50 s): the JSON and the text have both, each one's error; a state
    whose leg time is no duration is an undecodable record, not a crash."""
    progress = MissionProgress(5, Phase.FLYING, 2, current_target=1, leg_s=52.0)
    state = UavState(1, True, 1.0, 0, None, None, progress, phase=Phase.FLYING)
    timeline = tour_of_two()
    said = build_timeline([*tour_messages(), message(8.0, "fleet/uav/1/state", state)])
    (log,) = said.missions
    assert [row.get("begun_s") for row in log.legs(1, said.tracks)] == [None, 52.0]
    legs = report_json(said)["missions"][0]["legs"]["1"]
    assert [(leg["begun_s"], leg["begun_error"], leg["off"]) for leg in legs] == [
        (None, None, False),
        (52.0, 0.04, True),
    ]
    assert any(
        "1 (75.0 s predicted, 50.0 s flown; 52.0 s when begun) OFF by +50 %" in line
        for line in report_lines(said)
    )
    assert report_lines(timeline) != report_lines(said)
    good = message(8.0, "fleet/uav/1/state", state)
    bad = dataclasses.replace(good, data=good.data.replace(b'"leg_s":52.0', b'"leg_s":-1.0'))
    assert bad.data != good.data
    assert build_timeline([*tour_messages(), bad]).undecodable == 1


def test_a_leg_is_flagged_by_each_prediction_off_and_says_which() -> None:
    """UAV 1 said 40 s for its leg to target 0 as it began it (the plan 45 s; flown 50 s:
    -20 % when begun, -10 % as planned) and 60 s to target 1 (the plan 75 s; flown 50 s:
    +20 % when begun, +50 % as planned): each flag names the prediction it is of, and
    the count closing the tour lines counts each."""
    states = [
        message(at, "fleet/uav/1/state", UavState(1, True, 1.0, 0, None, None, progress,
                                                  phase=Phase.FLYING))
        for at, progress in (
            (3.0, MissionProgress(5, Phase.FLYING, 2, current_target=0, leg_s=40.0)),
            (8.0, MissionProgress(5, Phase.FLYING, 2, current_target=1, leg_s=60.0)),
        )
    ]  # fmt: skip
    timeline = build_timeline([*tour_messages(), *states])
    legs = report_json(timeline)["missions"][0]["legs"]["1"]
    assert [(leg["off"], leg["begun_off"], leg["begun_error"]) for leg in legs] == [
        (False, True, -0.2),
        (True, True, 0.2),
    ]
    lines = report_lines(timeline)
    assert any(
        "0 (45.0 s predicted, 50.0 s flown; 40.0 s when begun) OFF by -20 % when begun, "
        "1 (75.0 s predicted, 50.0 s flown; 60.0 s when begun) OFF by +50 % as planned, "
        "+20 % when begun" in line
        for line in lines
    ), lines
    assert any(
        "1 leg(s) predicted off the time flown by more than 10% as planned, 2 as timed when "
        "begun" in line
        for line in lines
    ), lines


def test_a_tour_after_a_re_plan_has_the_dropped_uav_s_targets(tmp_path: Path) -> None:
    """UAV 2 drops out; the re-plan appends its target 1 to UAV 1's queue: the report's
    tour of UAV 1 is 0 then 1, UAV 2's stays what it committed to."""
    first: dict[int, tuple[int, ...]] = {1: (0,), 2: (1,)}
    commit = {
        uav: AssignmentReport(5, uav, first[uav][0], {1: 0, 2: 1}, (), (1, 2), "d1",
                              queues=first, arrivals={1: (45.0,), 2: (50.0,)})
        for uav in (1, 2)
    }  # fmt: skip
    replan = AssignmentReport(
        5, 1, 0, {1: 0}, (), (1, 2), "d2", epoch=1, released=(2,),
        queues={1: (0, 1)}, arrivals={1: (45.0, 130.0)},
    )  # fmt: skip
    messages = [
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, (1, 2), TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", commit[1]),
        message(2.1, "fleet/mission/5/assignment/2", commit[2]),
        message(9.0, "fleet/mission/5/replan/1", replan),
    ]
    (log,) = build_timeline(messages).missions
    assert log.queue_of(1) == (0, 1)
    assert log.queue_of(2) == (1,)
    assert log.assignments[1].epoch == 0  # the commitment itself is unchanged


def test_the_arrival_chart_has_every_queued_target(tmp_path: Path) -> None:
    """A queue of two: both targets in the chart, predicted and flown from commitment."""
    tour = AssignmentReport(
        5, 1, 0, {1: 0}, (), (1,), "d1", eta_s=45.0,
        queues={1: (0, 1)}, arrivals={1: (45.0, 120.0)},
    )  # fmt: skip
    messages = [
        *(telemetry(t, 1, 35.72, -120.80 + 0.004 * t, 100 + 10 * t) for t in range(0, 14)),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, (1,), TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", tour),
        message(7.0, "fleet/mission/5/outcome/1", TargetOutcome(5, 1, 0, Phase.REACHED)),
        message(12.0, "fleet/mission/5/outcome/1", TargetOutcome(5, 1, 1, Phase.REACHED)),
    ]
    timeline = build_timeline(messages)
    (log,) = timeline.missions
    assert arrival_bars(log, timeline.tracks) == [(1, 0, 45.0, 50.0), (1, 1, 120.0, 100.0)]
    # One target each, no queue in the plan: its ETA and the time flown.
    (single,) = build_timeline(mission_messages()).missions
    tracks = build_timeline(mission_messages()).tracks
    assert arrival_bars(single, tracks) == [(1, 0, 45.0, pytest.approx(50.0)), (2, 1, 30.0, None)]


def test_panels_come_in_time_order() -> None:
    """UAV 1 reaches its target (5 s) before UAV 2 changes course (6 s)."""
    messages = [
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, TEAM, TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", report(1, 0, 45.0)),
        message(2.5, "fleet/mission/5/assignment/2", report(2, 1, 30.0)),
        message(3.0, "fleet/uav/1/track", Track(90)),
        message(5.0, "fleet/uav/1/status", StatusText("arrived", StatusKind.REACHED, 5, 0)),
        message(6.0, "fleet/uav/2/track", Track(90)),
    ]
    timeline = build_timeline(messages)
    (log,) = timeline.missions
    chosen = panels(timeline, log, [])
    assert [p.title for p in chosen] == ["sent", "committed", "reached", "course change"]
    asked = panels(timeline, log, [4.0, "sent"])
    assert [p.title for p in asked] == ["sent", "t = 4 s"]


def test_each_mission_s_panels_draw_its_own_tracks_only() -> None:
    """Mission 6 is sent at 20 s: its panels hold the track from then on, not before."""
    messages = [
        *(telemetry(t, 1, 35.72, -120.80 + 0.004 * t, 100 + 10 * t) for t in range(0, 30)),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, (1,), TARGETS)),
        message(20.0, "fleet/mission/6/targets", MissionTargets(6, (1,), TARGETS)),
    ]
    timeline = build_timeline(messages)
    first, second = timeline.missions
    track = timeline.tracks[1]
    assert [track.times[i] for i in mission_window(track, first)] == [
        float(t) for t in range(1, 21)
    ]
    assert track.times[mission_window(track, second).start] == 20.0


def test_an_earlier_mission_s_arrival_is_not_this_one_s() -> None:
    """UAV 1, still flying mission 4, commits to mission 5 and then says it reached
    mission 4's target: mission 5's target is not reached by that."""
    said = StatusText("reached target 0", StatusKind.REACHED, 4, 0)
    messages = [
        *(telemetry(t, 1, 35.72, -120.80 + 0.004 * t, 100 + 10 * t) for t in range(0, 12)),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, TEAM, TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", report(1, 0, 45.0)),
        message(2.2, "fleet/uav/1/status", said),
    ]
    (log,) = build_timeline(messages).missions
    assert log.reached == {} and log.flown_s == {}


def test_no_telemetry_between_commit_and_arrival_is_no_time_flown_not_zero() -> None:
    """The recording lost UAV 1's telemetry from 1 s to 9 s: its flight is not 0 s."""
    messages = [
        telemetry(0.0, 1, 35.72, -120.80, 100.0),
        message(1.0, "fleet/mission/5/targets", MissionTargets(5, (1,), TARGETS)),
        message(2.0, "fleet/mission/5/assignment/1", report(1, 0, 45.0)),
        message(8.0, "fleet/uav/1/status", StatusText("arrived", StatusKind.REACHED, 5, 0)),
        telemetry(9.0, 1, 35.72, -120.76, 190.0),
    ]
    timeline = build_timeline(messages)
    (log,) = timeline.missions
    assert log.reached == {1: 8.0} and log.flown_s == {}
    assert any("flown -" in line for line in report_lines(timeline))
