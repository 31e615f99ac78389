"""Which warnings and errors the status box keeps pinned (`ground.alerts`)."""

from __future__ import annotations

from fleet.mission.status_kind import StatusKind
from ground.alerts import Alerts, StatusRecord

K = StatusKind


def feed(alerts: Alerts, *messages: tuple[int, str, StatusKind, int | None]) -> list[str]:
    for t, (uav, text, kind, mission) in enumerate(messages):
        alerts.add(StatusRecord(float(t), uav, text, kind, mission))
    return [f"{a.uav}: {a.text}" for a in alerts.pinned()]


def test_info_streams_past_and_warnings_stay_through_any_flood() -> None:
    alerts = Alerts()
    flood = [(74, f"mission 1: tick {i}", K.COMPUTING, 1) for i in range(500)]
    declined = "warning: mission 1: no GPS telemetry yet: not taking part"
    pinned = feed(alerts, (74, declined, K.NOT_TAKING_PART, 1), *flood)
    assert pinned == [f"74: {declined}"]


def test_the_kind_carried_is_what_counts_not_the_text() -> None:
    pinned = feed(
        Alerts(), (74, "GPS fix degraded", K.ERROR, None), (74, "warning: said so", K.INFO, None)
    )
    assert pinned == ["74: GPS fix degraded"]


def test_link_lost_clears_only_when_the_link_is_back() -> None:
    alerts = Alerts()
    lost = (112, "error: autopilot link lost: no telemetry for over 3 s", K.LINK_LOST, None)
    assert feed(
        alerts,
        lost,
        (112, "mission 9: computing", K.COMPUTING, 9),
        (74, "autopilot link back", K.LINK_BACK, None),
        (112, "autopilot link back, says the text", K.INFO, None),
    )
    assert (
        feed(alerts, (112, "autopilot link back: telemetry flowing again", K.LINK_BACK, None)) == []
    )


def test_a_later_mission_clears_what_went_wrong_in_the_old_one() -> None:
    alerts = Alerts()
    pinned = feed(
        alerts,
        (74, "mission 2: computing approach times to 2 targets", K.COMPUTING, 2),
        (74, "warning: target not reached: autopilot left the target route", K.NOT_REACHED, 2),
        (74, "mission 2: flying to target 0", K.FLYING_TO_TARGET, 2),  # the same mission
    )
    assert pinned == ["74: warning: target not reached: autopilot left the target route"]
    assert feed(alerts, (112, "mission 3: computing", K.COMPUTING, 3)) != []  # another UAV's
    assert feed(alerts, (74, "the text names mission 3", K.INFO, None)) != []  # text: no
    assert feed(alerts, (74, "mission 3: computing", K.COMPUTING, 3)) == []


def test_an_alert_about_no_mission_is_about_the_last_one_named() -> None:
    alerts = Alerts()
    feed(alerts, (74, "mission 4: computing", K.COMPUTING, 4), (74, "error: x", K.ERROR, None))
    assert feed(alerts, (74, "mission 4: adopted", K.ADOPTED, 4)) == ["74: error: x"]
    assert feed(alerts, (74, "mission 5: computing", K.COMPUTING, 5)) == []


def test_an_opm_refusal_clears_with_the_module_s_answer() -> None:
    alerts = Alerts()
    assert feed(alerts, (74, "error: OPM status rate -1.0 refused", K.OPM_REFUSED, None))
    assert feed(alerts, (74, "module on, status every 1 s", K.MODULE_SET, None)) == []


def test_pinned_alerts_are_bounded_per_uav_and_in_all() -> None:
    alerts = Alerts(per_uav=2, max_pinned=3)
    pinned = feed(
        alerts,
        (1, "warning: a", K.WARNING, None),
        (1, "warning: b", K.WARNING, None),
        (1, "error: c", K.ERROR, None),
        (2, "warning: d", K.WARNING, None),
        (3, "warning: e", K.WARNING, None),
    )
    assert pinned == ["1: error: c", "2: warning: d", "3: warning: e"]
