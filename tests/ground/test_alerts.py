"""Which warnings and errors the status box keeps pinned (`ground.alerts`)."""

from __future__ import annotations

from fleet.mission.phase import Severity
from ground.alerts import Alerts, StatusRecord, mission_named

INFO, WARNING, ERROR = Severity.INFO, Severity.WARNING, Severity.ERROR


def feed(alerts: Alerts, *messages: tuple[int, str, Severity]) -> list[str]:
    for t, (uav, text, severity) in enumerate(messages):
        alerts.add(StatusRecord(float(t), uav, text, severity))
    return [f"{a.uav}: {a.text}" for a in alerts.pinned()]


def test_mission_named() -> None:
    assert mission_named("mission 12: target 0 chosen") == 12
    assert mission_named("error: mission 3: cannot fly the target: x") == 3
    assert mission_named("module on; tracking waypoint 90") is None
    assert mission_named("submission 4") is None


def test_info_streams_past_and_warnings_stay_through_any_flood() -> None:
    alerts = Alerts()
    flood = [(74, f"mission 1: tick {i}", INFO) for i in range(500)]
    pinned = feed(
        alerts, (74, "warning: mission 1: no GPS telemetry yet: not taking part", WARNING), *flood
    )
    assert pinned == ["74: warning: mission 1: no GPS telemetry yet: not taking part"]


def test_the_severity_carried_is_what_counts_not_the_text() -> None:
    pinned = feed(Alerts(), (74, "GPS fix degraded", ERROR), (74, "warning: said so", INFO))
    assert pinned == ["74: GPS fix degraded"]


def test_link_lost_clears_only_when_the_link_is_back() -> None:
    alerts = Alerts()
    lost = (112, "error: autopilot link lost: no telemetry for over 3 s", ERROR)
    assert feed(
        alerts, lost, (112, "mission 9: computing", INFO), (74, "autopilot link back", INFO)
    )
    assert feed(alerts, (112, "autopilot link back: telemetry flowing again", INFO)) == []


def test_a_later_mission_clears_what_went_wrong_in_the_old_one() -> None:
    alerts = Alerts()
    pinned = feed(
        alerts,
        (74, "mission 2: computing approach times to 2 targets", INFO),
        (74, "warning: target not reached: autopilot left the target route", WARNING),
        (74, "mission 2: flying to target 0", INFO),  # the same mission: still pinned
    )
    assert pinned == ["74: warning: target not reached: autopilot left the target route"]
    assert feed(alerts, (112, "mission 3: computing", INFO)) != []  # another UAV's news
    assert feed(alerts, (74, "mission 3: computing", INFO)) == []


def test_an_opm_refusal_clears_with_the_module_s_answer() -> None:
    alerts = Alerts()
    assert feed(alerts, (74, "error: OPM status rate -1.0 refused", ERROR))
    assert feed(alerts, (74, "module on, status every 1 s", INFO)) == []


def test_pinned_alerts_are_bounded_per_uav_and_in_all() -> None:
    alerts = Alerts(per_uav=2, max_pinned=3)
    pinned = feed(
        alerts,
        (1, "warning: a", WARNING),
        (1, "warning: b", WARNING),
        (1, "error: c", ERROR),
        (2, "warning: d", WARNING),
        (3, "warning: e", WARNING),
    )
    assert pinned == ["1: error: c", "2: warning: d", "3: warning: e"]
