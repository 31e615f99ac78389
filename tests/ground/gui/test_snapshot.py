"""The page's snapshot: target states, status severity, trails, and the coalesced push rate."""

from __future__ import annotations

import asyncio
import threading
import time

from fleet.mission.messages import AssignmentReport, Target, UavResult
from fleet.mission.status_kind import StatusKind
from ground.alerts import StatusRecord
from ground.fleet_view import UavView
from ground.gui.snapshot import Coalescer, GuiModel, target_states
from ground.mission_outcome import MissionOutcome

TARGETS = (Target(35.72, -120.76, 600.0), Target(35.71, -120.75, 600.0), Target(35.7, -120.7, 0))


def _report(uav: int, target: int | None) -> AssignmentReport:
    return AssignmentReport(
        mission=3,
        uav=uav,
        target=target,
        pairs={74: 0, 112: 1},
        unassigned=(2,),
        team=(74, 112),
        digest="d",
        eta_s=100.0 + uav,
    )


def _outcome(*reports: AssignmentReport) -> MissionOutcome:
    outcome = MissionOutcome(3, (74, 112), TARGETS)
    outcome.assignments = {r.uav: r for r in reports}
    return outcome


def _states(outcome: MissionOutcome, views: dict[int, UavView], **kw: object) -> list[str]:
    reached = kw.get("reached", set())
    aborted = bool(kw.get("aborted", False))
    assert isinstance(reached, set)
    return [s["state"] for s in target_states(outcome, views, reached, aborted)]


def test_targets_are_pending_until_the_team_committed_then_unserved() -> None:
    assert _states(_outcome(), {}) == ["pending"] * 3
    assert _states(_outcome(_report(74, 0)), {}) == ["assigned", "pending", "pending"]
    both = _outcome(_report(74, 0), _report(112, 1))
    assert _states(both, {}) == ["assigned", "assigned", "unserved"]
    first = target_states(both, {}, set(), False)[0]
    assert first == {"index": 0, "state": "assigned", "uav": 74, "eta_s": 174.0}


def test_a_target_is_reached_when_its_uav_says_so_and_stays_reached() -> None:
    both = _outcome(_report(74, 0), _report(112, 1))
    views = {74: UavView(id=74, mission=3, phase="reached", target=0)}
    assert _states(both, views) == ["reached", "assigned", "unserved"]
    assert _states(both, {}, reached={112}, aborted=True) == ["aborted", "reached", "unserved"]


def test_the_page_keeps_warnings_and_errors_in_view_by_the_kind_carried() -> None:
    model = GuiModel()
    flying = StatusKind.FLYING_TO_TARGET
    model.add_status(StatusRecord(0.5, 74, "mission 1: flying to target 0", flying, 1))
    model.add_status(StatusRecord(1.0, 74, "GPS fix degraded", StatusKind.WARNING))
    for tick in range(600):  # more than the status history holds
        model.add_status(StatusRecord(2.0 + tick, 74, f"mission 1: tick {tick}", flying, 1))
    assert [(a["uav"], a["text"], a["severity"]) for a in model.alerts_json()] == [
        (74, "GPS fix degraded", "warning")
    ]
    later = StatusRecord(700.0, 74, "mission 2: computing", StatusKind.COMPUTING, 2)
    model.add_status(later)  # a later mission
    assert model.alerts_json() == []


def test_the_model_keeps_trails_statuses_and_reached_uavs() -> None:
    model = GuiModel()
    for lat in (35.0, 35.00001, 35.001):  # the middle one is within a trail step
        model.note_views([UavView(id=74, lat=lat, lon=-120.0, mission=3, phase="reached")])
    assert model.uav_json(UavView(id=74))["trail"] == [[35.0, -120.0], [35.001, -120.0]]
    assert (3, 74) in model.reached
    model.add_status(StatusRecord(1.0, 74, "boom", StatusKind.CANNOT_FLY, 3))
    assert [s["severity"] for s in model.new_statuses()] == ["error"]
    assert model.new_statuses() == []
    assert model.uav_json(UavView(id=74, telemetry_age_s=9.0))["link_lost"] is True
    outcome = _outcome(_report(74, 0))
    outcome.results = {74: UavResult(3, 74, (1.0, 2.0, 3.0))}
    mission = model.mission_json(outcome, [])
    assert mission is not None and mission["results_received"] == 1
    assert mission["target_states"][0]["state"] == "reached"


def test_pushes_are_bounded_by_the_rate_whatever_the_marks() -> None:
    """Four threads mark 20,000 times as fast as they can: at most rate x time pushes."""
    rate_hz = 10.0

    async def scenario() -> tuple[int, int, float]:
        pushed = asyncio.Event()

        async def push() -> None:
            pushed.set()

        coalescer = Coalescer(push, rate_hz)
        runner = asyncio.create_task(coalescer.run())

        def storm() -> None:
            for _ in range(5000):
                coalescer.mark_threadsafe()

        started = time.monotonic()
        threads = [threading.Thread(target=storm) for _ in range(4)]
        for thread in threads:
            thread.start()
        while any(thread.is_alive() for thread in threads):
            await asyncio.sleep(0.01)
        await pushed.wait()
        elapsed = time.monotonic() - started
        runner.cancel()
        await asyncio.gather(runner, return_exceptions=True)
        return coalescer.marks, coalescer.pushes, elapsed

    marks, pushes, elapsed = asyncio.run(scenario())
    assert marks == 20000
    assert 1 <= pushes <= elapsed * rate_hz + 1


def test_a_target_whose_holder_aborted_alone_reads_aborted_with_no_eta() -> None:
    both = _outcome(_report(74, 0), _report(112, 1))
    views = [
        UavView(id=74, mission=3, phase="aborted"),
        UavView(id=112, mission=3, phase="flying", target=1),
    ]
    mission = GuiModel().mission_json(both, views)
    assert mission is not None
    first, second, _ = mission["target_states"]
    assert first == {
        "index": 0,
        "state": "aborted",
        "uav": 74,
        "eta_s": None,
        "reason": "UAV 74 aborted",
    }
    assert second == {"index": 1, "state": "assigned", "uav": 112, "eta_s": 212.0}
    assert mission["success"] is False


def test_a_failed_or_preempted_holder_s_target_says_so_and_an_aborted_mission_has_no_eta() -> None:
    both = _outcome(_report(74, 0), _report(112, 1))
    both.note_phase(74, "failed", "no echo", 3)
    both.note_phase(112, "preempted", "track to waypoint 1", 3)
    states = target_states(both, {}, set(), aborted=True)
    assert [(s["state"], s["reason"], s["eta_s"]) for s in states[:2]] == [
        ("failed", "no echo", None),
        ("preempted", "track to waypoint 1", None),
    ]
    later = _outcome(_report(74, 0))
    later.note_phase(74, "aborted", None, 4)  # another mission's phase
    assert _states(later, {}) == ["assigned", "pending", "pending"]
