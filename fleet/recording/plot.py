"""`fleet plot`: a mission as the thesis draws it (figures 4-1, 4-3), with matplotlib.

One figure per mission (`--mission`, the last by default): one map panel per event
(sent, committed, course change, reached, resumed, or the times asked for), in time
order: every UAV's track in this mission so far (from its sending) in its own colour
with its ID at its position, its course still to come in this mission faint, the
mission's no-fly zones hatched red, the targets as red X with their index, and a
dashed line from each committed UAV to its target. A last panel compares, for every
target of each UAV's queue, the predicted arrival (from its commitment) with the time
it flew. Drawn with the Agg backend on a `Figure` (no pyplot state), so no display is
needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from fleet.errors import FleetError
from fleet.geo.mercator import MercatorProjection
from fleet.recording.mission_log import MissionLog, Timeline, Track

EVENT_NAMES = ("sent", "committed", "course change", "reached", "resumed")
COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:cyan")
COLUMNS = 3


class PlotError(FleetError, ValueError):
    """What to draw was asked for wrongly (an unknown event, a mission not recorded)."""


@dataclass(frozen=True)
class Panel:
    title: str
    at: float  #: seconds since the recording's start


def parse_at(text: str) -> list[str | float]:
    """`--at sent,reached,42.5` -> event names and times (s since the recording's start)."""
    wanted: list[str | float] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if part in EVENT_NAMES:
            wanted.append(part)
            continue
        try:
            seconds = float(part)
        except ValueError:
            raise PlotError(
                f"--at: {part!r} is neither an event ({', '.join(EVENT_NAMES)}) nor seconds"
            ) from None
        if not math.isfinite(seconds) or seconds < 0:
            raise PlotError(f"--at: {part!r} must be a time >= 0")
        wanted.append(seconds)
    return wanted


def choose_mission(timeline: Timeline, mission: int | None) -> MissionLog | None:
    if mission is None:
        return timeline.missions[-1] if timeline.missions else None
    for log in timeline.missions:
        if log.mission == mission:
            return log
    recorded = ", ".join(str(m.mission) for m in timeline.missions) or "none"
    raise PlotError(f"mission {mission} is not in the recording (recorded: {recorded})")


def panels(timeline: Timeline, log: MissionLog | None, at: list[str | float]) -> list[Panel]:
    """The map panels, in time order."""
    events = log.events() if log is not None else {}
    if not at:
        chosen = sorted((Panel(name, t) for name, t in events.items()), key=lambda p: p.at)
        return chosen or [Panel("end of recording", timeline.end)]
    found = []
    for item in at:
        if isinstance(item, float):
            found.append(Panel(f"t = {item:g} s", min(item, timeline.end)))
        elif item in events:
            found.append(Panel(item, events[item]))
        else:
            happened = ", ".join(events) or "none"
            raise PlotError(f"--at {item}: not in this mission (events seen: {happened})")
    return sorted(found, key=lambda p: p.at)


def render(
    timeline: Timeline,
    out: Path,
    *,
    mission: int | None = None,
    at: list[str | float] | None = None,
) -> Path:
    """Draw the figure into `out` (PNG, or any format matplotlib knows by suffix)."""
    log = choose_mission(timeline, mission)
    chosen = panels(timeline, log, at or [])
    count = len(chosen) + (1 if log is not None else 0)
    rows = math.ceil(count / COLUMNS)
    columns = min(COLUMNS, count)
    figure = Figure(figsize=(5.2 * columns, 5.0 * rows), dpi=90, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, columns, squeeze=False).ravel()
    projection = _projection(timeline, log)
    limits = _limits(timeline, log, projection)
    for ax, panel in zip(axes, chosen, strict=False):
        _map_panel(ax, timeline, log, panel, projection, limits)
    if log is not None:
        _arrival_panel(axes[len(chosen)], log, sorted(timeline.tracks), timeline.tracks)
    for ax in axes[count:]:
        ax.set_visible(False)
    title = "recording" if log is None else f"mission {log.mission}"
    figure.suptitle(f"{title}: team {', '.join(map(str, sorted(timeline.tracks)))}")
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out)
    return out


def mission_window(track: Track, log: MissionLog | None) -> range:
    """The indices of the track's points within the mission (from its sending to the next
    mission's), or all of them with no mission."""
    if log is None:
        return range(len(track.times))
    return range(track.until(log.sent - 1e-9), track.until(log.end))


def _mission_points(track: Track, log: MissionLog | None) -> list[tuple[float, float]]:
    return [(track.lat[i], track.lon[i]) for i in mission_window(track, log)]


def _projection(timeline: Timeline, log: MissionLog | None) -> MercatorProjection:
    points = [(t.lat, t.lon) for t in log.targets] if log is not None else []
    for track in timeline.tracks.values():
        points += _mission_points(track, log)
    if not points:
        return MercatorProjection(0.0, 0.0)
    return MercatorProjection(
        sum(p[0] for p in points) / len(points), sum(p[1] for p in points) / len(points)
    )


def _km(projection: MercatorProjection, lat: float, lon: float) -> tuple[float, float]:
    x, y = projection.to_xy(lat, lon)
    return x / 1000.0, y / 1000.0


def _limits(
    timeline: Timeline, log: MissionLog | None, projection: MercatorProjection
) -> tuple[float, float, float, float]:
    xs: list[float] = []
    ys: list[float] = []
    places = [(t.lat, t.lon) for t in log.targets] if log is not None else []
    places += [p for zone in log.zones for p in zone.ring] if log is not None else []
    for track in timeline.tracks.values():
        places += _mission_points(track, log)
    for lat, lon in places:
        x, y = _km(projection, lat, lon)
        xs.append(x)
        ys.append(y)
    if not xs:
        return (-1.0, 1.0, -1.0, 1.0)
    margin = 0.08 * max(max(xs) - min(xs), max(ys) - min(ys), 0.5)
    return (min(xs) - margin, max(xs) + margin, min(ys) - margin, max(ys) + margin)


def _colour(uav: int, order: list[int]) -> str:
    return COLOURS[order.index(uav) % len(COLOURS)] if uav in order else "grey"


def _map_panel(
    ax: Axes,
    timeline: Timeline,
    log: MissionLog | None,
    panel: Panel,
    projection: MercatorProjection,
    limits: tuple[float, float, float, float],
) -> None:
    order = sorted(timeline.tracks)
    for uav, track in sorted(timeline.tracks.items()):
        colour = _colour(uav, order)
        window = mission_window(track, log)
        points = [_km(projection, track.lat[i], track.lon[i]) for i in window]
        if log is not None:
            # The course still to come, faint, within this mission.
            ax.plot(*_xy(points), color=colour, alpha=0.15, linewidth=1)
        flown = points[: max(0, track.until(panel.at) - window.start)]
        if not flown:
            continue
        ax.plot(*_xy(flown), color=colour, linewidth=1.8, label=f"UAV {uav}")
        x, y = flown[-1]
        ax.plot([x], [y], marker="o", color=colour, markersize=7)
        ax.annotate(str(uav), (x, y), xytext=(5, 5), textcoords="offset points", color=colour)
    if log is not None:
        _zones(ax, log, projection)
        _targets(ax, log, panel, timeline, projection, order)
    ax.set_xlim(limits[0], limits[1])
    ax.set_ylim(limits[2], limits[3])
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"{panel.title} (t = {panel.at:.1f} s)")
    ax.set_xlabel("east (km)")
    ax.set_ylabel("north (km)")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize="small")


def _targets(
    ax: Axes,
    log: MissionLog,
    panel: Panel,
    timeline: Timeline,
    projection: MercatorProjection,
    order: list[int],
) -> None:
    if panel.at < log.sent:
        return  # not sent yet
    for index, place in enumerate(log.targets):
        x, y = _km(projection, place.lat, place.lon)
        ax.plot([x], [y], marker="x", color="red", markersize=11, markeredgewidth=2.5)
        ax.annotate(str(index), (x, y), xytext=(6, -12), textcoords="offset points", color="red")
    for uav, committed in log.committed.items():
        target = log.target_of(uav)
        track = timeline.tracks.get(uav)
        if target is None or track is None or committed > panel.at:
            continue
        if uav in log.reached and log.reached[uav] <= panel.at:
            continue  # reached: the line has done its job
        if uav in log.ended and log.ended[uav][0] <= panel.at:
            continue  # aborted, preempted, failed: nobody flies that line any more
        position = track.position(panel.at)
        if position is None:
            continue
        start = _km(projection, *position)
        goal = _km(projection, log.targets[target].lat, log.targets[target].lon)
        ax.plot(*_xy([start, goal]), linestyle="--", color=_colour(uav, order), linewidth=1)
    _draw_tours(ax, log, projection, order)


def _draw_tours(
    ax: Axes, log: MissionLog, projection: MercatorProjection, order: list[int]
) -> None:
    """Each UAV's queue of more than one target: a dotted line through it."""
    for uav in log.team:
        queue = log.queue_of(uav)
        if len(queue) < 2:
            continue
        points = [_km(projection, log.targets[t].lat, log.targets[t].lon) for t in queue]
        ax.plot(*_xy(points), linestyle=":", color=_colour(uav, order), linewidth=1.2)


def _zones(ax: Axes, log: MissionLog, projection: MercatorProjection) -> None:
    """The mission's no-fly zones, hatched red, under the tracks flown around them."""
    for index, zone in enumerate(log.zones):
        points = [_km(projection, lat, lon) for lat, lon in zone.ring]
        ax.fill(*_xy(points), facecolor="red", alpha=0.12, edgecolor="red", hatch="//")
        ax.annotate(zone.name or f"zone {index}", points[0], color="darkred", fontsize="small")


def _xy(points: list[tuple[float, float]]) -> tuple[list[float], list[float]]:
    return [p[0] for p in points], [p[1] for p in points]


def _arrival_panel(ax: Axes, log: MissionLog, order: list[int], tracks: dict[int, Track]) -> None:
    """Per target of each UAV's queue, in its colour: the predicted arrival from its
    commitment (hatched) beside the time it flew to get there (aircraft clock)."""
    bars = arrival_bars(log, tracks)
    width = 0.38
    for p, (uav, _, predicted, flown) in enumerate(bars):
        colour = _colour(uav, order)
        for offset, value, hatch, alpha in (
            (-width / 2, predicted, "//", 0.35),
            (width / 2, flown, None, 0.9),
        ):
            if value is None:
                ended = log.ended.get(uav)
                missing = "not reached" if ended is None else f"{ended[1]}, not reached"
                ax.annotate(
                    missing if offset > 0 else "no ETA",
                    (p + offset, 0),
                    ha="center",
                    va="bottom",
                    color="red",
                    rotation=90,
                )
                continue
            ax.bar(p + offset, value, width, color=colour, alpha=alpha, hatch=hatch)
            ax.annotate(f"{value:.0f} s", (p + offset, value), ha="center", va="bottom")
    # Legend entries in neutral grey: the colours are the UAVs'.
    ax.bar([0], [0], 0, color="grey", alpha=0.35, hatch="//", label="predicted (ETA)")
    ax.bar([0], [0], 0, color="grey", alpha=0.9, label="flown")
    positions = list(range(len(bars)))
    ax.set_xticks(positions, [f"UAV {uav}\ntarget {target}" for uav, target, _, _ in bars])
    ax.set_ylabel("s from commitment to target (aircraft clock)")
    ax.margins(y=0.12)
    ax.set_title("arrival: predicted vs flown")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(loc="best", fontsize="small")


def arrival_bars(
    log: MissionLog, tracks: dict[int, Track]
) -> list[tuple[int, int, float | None, float | None]]:
    """(UAV, target, predicted s, flown s) for every target of each UAV's queue, in queue
    order, both counted from the UAV's commitment; None where unknown (a leg not flown)."""
    bars: list[tuple[int, int, float | None, float | None]] = []
    for uav in log.team:
        planned = 0.0
        flown_so_far: float | None = 0.0
        for i, leg in enumerate(log.legs(uav, tracks) or _first_leg(log, uav)):
            planned_leg, flown_leg = leg["predicted_s"], leg["flown_s"]
            if i == 0:  # a plan without arrivals, no outcome heard: its ETA, its arrival
                planned_leg = log.predicted_s(uav) if planned_leg is None else planned_leg
                flown_leg = log.flown_s.get(uav) if flown_leg is None else flown_leg
            planned = planned + planned_leg if planned_leg is not None else planned
            flown_so_far = (
                None if flown_so_far is None or flown_leg is None else flown_so_far + flown_leg
            )
            bars.append(
                (uav, leg["target"], planned if planned_leg is not None else None, flown_so_far)
            )
    return bars


def _first_leg(log: MissionLog, uav: int) -> list[dict[str, Any]]:
    """A UAV's one target without a queue in its plan: its ETA and the time it flew."""
    target = log.target_of(uav)
    if target is None:
        return []
    return [
        {"target": target, "predicted_s": log.predicted_s(uav), "flown_s": log.flown_s.get(uav)}
    ]
