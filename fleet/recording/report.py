"""`fleet report`: each mission of a recording, as text or JSON (pure)."""

from __future__ import annotations

from typing import Any

from fleet.recording.mission_log import MissionLog, Timeline, Track
from fleet.recording.streams import stopped_telemetry


def _round(value: float | None, digits: int = 1) -> float | None:
    return None if value is None else round(value, digits)


def mission_json(log: MissionLog, tracks: dict[int, Track] | None = None) -> dict[str, Any]:
    tracks = tracks or {}
    committed = log.all_committed
    return {
        "mission": log.mission,
        "team": list(log.team),
        "targets": [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in log.targets],
        "approach_times_s": {
            str(uav): [_round(t) for t in result.times] for uav, result in log.results.items()
        },
        "assignment": {str(uav): log.target_of(uav) for uav in log.team},
        "agreed": log.agreed,
        "digests": {str(uav): report.digest for uav, report in log.assignments.items()},
        "predicted_s": {str(uav): _round(log.predicted_s(uav)) for uav in log.team},
        "flown_s": {str(uav): _round(log.flown_s.get(uav)) for uav in log.team},
        "reached": {str(uav): uav in log.reached for uav in log.team},
        "reached_how": {str(uav): how for uav, how in log.reached_how.items()},
        "ended": {
            str(uav): {"at_s": round(t, 3), "how": how} for uav, (t, how) in log.ended.items()
        },
        "sent_at_s": round(log.sent, 3),
        "send_to_commit_s": None if committed is None else round(committed - log.sent, 3),
        "faults": [{"at_s": round(t, 3), "what": what} for t, what in log.faults],
        "queues": {str(uav): list(log.queue_of(uav)) for uav in log.team},
        "legs": {str(uav): _rounded_legs(log.legs(uav, tracks)) for uav in log.team},
    }


#: A leg whose predicted time is off the flown one by more than this share is flagged.
LEG_TOLERANCE = 0.10


def leg_error(row: dict[str, Any], predicted_by: str = "predicted_s") -> float | None:
    """(predicted - flown) / flown of one leg, predicted by the plan (or `predicted_by`:
    "begun_s", the UAV's time said when it began the leg); None where either is missing."""
    predicted, flown = row.get(predicted_by), row["flown_s"]
    if predicted is None or flown is None or flown <= 0.0:
        return None
    return float((predicted - flown) / flown)


def leg_off(row: dict[str, Any], predicted_by: str = "predicted_s") -> bool:
    """The leg's time predicted by the plan (or `predicted_by`, as `leg_error`) is off
    the flown one by more than LEG_TOLERANCE."""
    error = leg_error(row, predicted_by)
    return error is not None and abs(error) > LEG_TOLERANCE


def _rounded_legs(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [
        {
            **row,
            "predicted_s": _round(row["predicted_s"]),
            "flown_s": _round(row["flown_s"]),
            "error": _round(leg_error(row), 3),
            "off": leg_off(row),
            "begun_s": _round(row.get("begun_s")),
            "begun_error": _round(leg_error(row, "begun_s"), 3),
            "begun_off": leg_off(row, "begun_s"),
        }
        for row in rows
    ]


def telemetry_problems(timeline: Timeline) -> list[str]:
    """Each UAV (with telemetry, or in a mission's team) whose telemetry stopped, or
    never began, while another UAV's went on."""
    uavs = set(timeline.tracks) | {uav for log in timeline.missions for uav in log.team}
    last: dict[int, float | None] = {}
    samples: dict[int, int] = {}
    for uav in uavs:
        track = timeline.tracks.get(uav)
        last[uav] = track.times[-1] if track is not None and track.times else None
        samples[uav] = len(track.times) if track is not None else 0
    return stopped_telemetry(last, samples)


def report_json(timeline: Timeline) -> dict[str, Any]:
    return {
        "duration_s": round(timeline.end, 3),
        "uavs": sorted(timeline.tracks),
        "telemetry_problems": telemetry_problems(timeline),
        "undecodable_messages": timeline.undecodable,
        "missions": [mission_json(log, timeline.tracks) for log in timeline.missions],
    }


def _seconds(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} s"


def report_lines(timeline: Timeline) -> list[str]:
    uavs = ", ".join(map(str, sorted(timeline.tracks))) or "none"
    lines = [f"recording: {timeline.end:.1f} s; UAVs with telemetry: {uavs}"]
    lines += [f"warning: {problem}" for problem in telemetry_problems(timeline)]
    if not timeline.missions:
        lines.append("no mission in this recording")
    for log in timeline.missions:
        lines += _mission_lines(log)
        lines += _tour_lines(log, timeline.tracks)
    return lines


def _tour_lines(log: MissionLog, tracks: dict[int, Track]) -> list[str]:
    """Each UAV with more than one target: its tour, predicted vs flown per leg; every
    leg (a first one too) off by more than LEG_TOLERANCE flagged, and counted, by each
    prediction: the plan's and the UAV's as it began the leg."""
    lines: list[str] = []
    off = begun_off = 0
    for uav in log.team:
        rows = log.legs(uav, tracks)
        off += sum(leg_off(row) for row in rows)
        begun_off += sum(leg_off(row, "begun_s") for row in rows)
        if len(rows) < 2:
            lines += [
                f"  UAV {uav} to {row['target']}: {_seconds(row['predicted_s'])} predicted, "
                f"{_seconds(row['flown_s'])} flown{_begun(row)}{_flag(row)}"
                for row in rows
                if leg_off(row) or leg_off(row, "begun_s")
            ]
            continue
        legs = ", ".join(
            f"{row['target']} ({_seconds(row['predicted_s'])} predicted, "
            f"{_seconds(row['flown_s'])} flown{_begun(row)}){_flag(row)}"
            for row in rows
        )
        lines.append(f"  UAV {uav} tour: {legs}")
    if off or begun_off:
        lines.append(
            f"  {off} leg(s) predicted off the time flown by more than {LEG_TOLERANCE:.0%} "
            f"as planned, {begun_off} as timed when begun"
        )
    return lines


def _begun(row: dict[str, Any]) -> str:
    """'; 221.5 s when begun' where the UAV said its time for the leg as it began it and
    that differs from the plan's."""
    begun = row.get("begun_s")
    if begun is None or begun == row["predicted_s"]:
        return ""
    return f"; {begun:.1f} s when begun"


def _flag(row: dict[str, Any]) -> str:
    """' OFF by +12 % as planned' (and/or '+11 % when begun') for a leg whose predicted
    time, by the plan or as the UAV timed it when it began it, is off the flown one by
    more than LEG_TOLERANCE; else nothing."""
    said = []
    for key, how in (("predicted_s", "as planned"), ("begun_s", "when begun")):
        error = leg_error(row, key)
        if leg_off(row, key) and error is not None:
            if key == "begun_s" and row.get("begun_s") == row["predicted_s"]:
                continue  # the same time: flagged once, as planned
            said.append(f"{100 * error:+.0f} % {how}")
    return f" OFF by {', '.join(said)}" if said else ""


def _mission_lines(log: MissionLog) -> list[str]:
    committed = log.all_committed
    lines = [
        f"mission {log.mission}: team {', '.join(map(str, log.team))}; "
        f"{len(log.targets)} targets; sent at {log.sent:.1f} s",
    ]
    for index, place in enumerate(log.targets):
        lines.append(f"  target {index}: {place.lat:.6f}, {place.lon:.6f}, {place.alt:.0f} m")
    for uav in log.team:
        result = log.results.get(uav)
        times = (
            "no result"
            if result is None
            else "approach " + ", ".join("-" if t is None else f"{t:.1f}" for t in result.times)
        )
        target = log.target_of(uav)
        choice = (
            "not committed"
            if uav not in log.assignments
            else ("no target" if target is None else f"target {target}")
        )
        arrival = ""
        if target is not None:
            flown = log.flown_s.get(uav)
            if uav in log.reached:
                outcome = f"flown {_seconds(flown)} ({log.reached_how[uav]})"
            elif uav in log.ended:
                at, how = log.ended[uav]
                outcome = f"{how.upper()} at {at:.1f} s, NOT reached"
            else:
                outcome = "NOT reached"
            arrival = f"; predicted {_seconds(log.predicted_s(uav))}, {outcome}"
        lines.append(f"  UAV {uav}: {choice}; {times}{arrival}")
    lines.append(f"  agreed: {'yes' if log.agreed else 'no'}")
    lines.append(
        "  send -> commit: "
        + ("not every UAV committed" if committed is None else f"{committed - log.sent:.2f} s")
    )
    if log.faults:
        lines.append("  faults:")
        lines += [f"    {t:.1f} s: {what}" for t, what in log.faults]
    else:
        lines.append("  faults: none seen")
    return lines
