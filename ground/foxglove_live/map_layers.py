"""What `fleet foxglove` draws on Foxglove's Map panel (pure: no I/O).

* Each UAV's position as a `foxglove.LocationFix`, from its telemetry: the same fields
  as the recorder's map fixes (`fleet.recording.channels.location_fix`), plus its
  heading and its colour.
* The current mission as one GeoJSON FeatureCollection, built from layers: each layer
  is a function of the `MissionMap` returning its features, so another drawing (a
  UAV's tour of several targets, say) is one more function in `LAYERS`.

A UAV's colour is the one the Mission Manager's page gives it (hues a golden angle
apart, ground/gui/static/app.js), so both views agree.
"""

from __future__ import annotations

import colorsys
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fleet.mission import claims
from fleet.mission.messages import AssignmentReport, MissionAbort, MissionTargets, TargetOutcome
from fleet.mission.phase import Phase
from fleet.recording import channels

#: The GeoJSON topic under the key prefix: `{prefix}/map/targets`.
TARGETS_TOPIC_LEAF = "map/targets"
#: GeoJSON colours of a target nobody flies to, and of one reached.
UNASSIGNED_COLOUR = "#d62728"
REACHED_COLOUR = "#2ca02c"

Feature = dict[str, Any]


def targets_topic(prefix: str) -> str:
    return f"{prefix}/{TARGETS_TOPIC_LEAF}"


# ---- colours ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rgb:
    """A colour, each channel 0-1."""

    r: float
    g: float
    b: float

    @property
    def hex(self) -> str:
        return "#" + "".join(f"{round(c * 255):02x}" for c in (self.r, self.g, self.b))


def colour_of(uav: int) -> Rgb:
    """hsl(uav * 137.508 mod 360, 75%, 38%): the page's colour of this Piccolo ID."""
    r, g, b = colorsys.hls_to_rgb((uav * 137.508) % 360 / 360, 0.38, 0.75)
    return Rgb(r, g, b)


# ---- LocationFix -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Fix:
    """The fields of one UAV's `foxglove.LocationFix`."""

    uav: int
    time_ns: int
    frame_id: str
    latitude: float
    longitude: float
    altitude: float
    heading_rad: float | None  #: clockwise from north; None without an attitude block
    colour: Rgb


def fix_of(telemetry: object, uav: int, time_ns: int) -> Fix | None:
    """The fix of a Telemetry (as JSON); None without a GPS block or off the globe."""
    if not isinstance(telemetry, dict):
        return None
    base = channels.location_fix(telemetry, uav, time_ns)
    if base is None:
        return None
    lat, lon, alt = base["latitude"], base["longitude"], base["altitude"]
    if not (math.isfinite(alt) and -90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return None
    return Fix(uav, time_ns, base["frame_id"], lat, lon, alt, _heading(telemetry), colour_of(uav))


def _heading(telemetry: dict[str, Any]) -> float | None:
    sensor = telemetry.get("sensor")
    yaw = sensor.get("yaw") if isinstance(sensor, dict) else None
    if isinstance(yaw, bool) or not isinstance(yaw, int | float) or not math.isfinite(yaw):
        return None
    return math.radians(yaw % 360.0)


# ---- the mission as the fleet reports it -----------------------------------------------------
@dataclass
class MissionMap:
    """The latest mission heard (a higher id supersedes a lower one), what each UAV
    committed to, how each UAV's part ended, and where each UAV is."""

    targets: MissionTargets | None = None
    #: Piccolo ID -> (epoch, target index or None) of its latest assignment report.
    assigned: dict[int, tuple[int, int | None]] = field(default_factory=dict)
    #: Piccolo ID -> its queue of targets in that report (its one target before queues).
    queues: dict[int, tuple[int, ...]] = field(default_factory=dict)
    outcomes: dict[int, TargetOutcome] = field(default_factory=dict)
    #: UAVs aborted alone; `team_aborted` when the whole team was.
    aborted: set[int] = field(default_factory=set)
    team_aborted: bool = False
    positions: dict[int, tuple[float, float]] = field(default_factory=dict)
    #: Each UAV's latest fix (altitude and heading too: the 3D scene draws them).
    fixes: dict[int, Fix] = field(default_factory=dict)

    @property
    def mission(self) -> int | None:
        return None if self.targets is None else self.targets.mission

    def on_targets(self, targets: MissionTargets) -> bool:
        """Whether it changed the map: a newer mission starts afresh, an older is ignored."""
        if self.targets is not None and targets.mission < self.targets.mission:
            return False
        if self.targets is None or targets.mission > self.targets.mission:
            self.assigned.clear()
            self.queues.clear()
            self.outcomes.clear()
            self.aborted.clear()
            self.team_aborted = False
        changed = targets != self.targets
        self.targets = targets
        return changed

    def on_assignment(self, report: AssignmentReport) -> bool:
        if report.mission != self.mission:
            return False
        previous = self.assigned.get(report.uav)
        if previous is not None and report.epoch < previous[0]:
            return False  # a re-plan already superseded it
        self.assigned[report.uav] = (report.epoch, report.target)
        queue = report.queues.get(report.uav) if report.queues else None
        if queue is None:
            queue = () if report.target is None else (report.target,)
        changed = self.queues.get(report.uav) != queue
        self.queues[report.uav] = queue
        return changed or previous != self.assigned[report.uav]

    def on_outcome(self, outcome: TargetOutcome) -> bool:
        if outcome.mission != self.mission or self.outcomes.get(outcome.uav) == outcome:
            return False
        self.outcomes[outcome.uav] = outcome
        return True

    def on_abort(self, abort: MissionAbort) -> bool:
        if abort.mission != self.mission:
            return False
        if abort.uav is None:
            changed, self.team_aborted = not self.team_aborted, True
            return changed
        changed = abort.uav not in self.aborted
        self.aborted.add(abort.uav)
        return changed

    def on_fix(self, fix: Fix) -> None:
        self.positions[fix.uav] = (fix.latitude, fix.longitude)
        self.fixes[fix.uav] = fix

    def target_of(self, uav: int) -> int | None:
        """The index of the target `uav` flies to, if it still does: the first of its
        queue not reached yet."""
        tour = self.tour_of(uav)
        return tour[0] if tour else None

    def tour_of(self, uav: int) -> tuple[int, ...]:
        """The targets `uav` still has to fly, in its queue's order."""
        entry = self.assigned.get(uav)
        if entry is None or self.team_aborted or uav in self.aborted:
            return ()
        outcome = self.outcomes.get(uav)
        if outcome is not None and outcome.phase is not Phase.REACHED:
            return ()  # failed or link lost: released, its targets re-planned
        reached = self.reached()
        return tuple(t for t in self.queues.get(uav, ()) if t not in reached)

    def tours(self) -> dict[int, tuple[int, ...]]:
        """Each UAV's `tour_of`, by UAV id in order, the mission's targets only (a report
        may name one it does not have); none before the mission is heard."""
        if self.targets is None:
            return {}
        count = len(self.targets.targets)
        return {
            uav: tuple(index for index in self.tour_of(uav) if index < count)
            for uav in sorted(self.queues)
        }

    def reached(self) -> dict[int, int]:
        """Every target a UAV said it reached itself, and by whom (a UAV's latest outcome
        names its last one; `reached` lists every one it knows of, along a queue: what it
        says of a teammate is not believed, `fleet.mission.claims`)."""
        return claims.reached_by(self.outcomes.values())


# ---- GeoJSON layers --------------------------------------------------------------------------
Layer = Callable[[MissionMap], list[Feature]]


def _feature(geometry: dict[str, Any], name: str, colour: str, **properties: Any) -> Feature:
    return {
        "type": "Feature",
        "geometry": geometry,
        "properties": {"name": name, "style": {"color": colour}, **properties},
    }


def target_points(view: MissionMap) -> list[Feature]:
    """Each target of the mission: who flies to it, and whether it was reached."""
    if view.targets is None:
        return []
    flyers = {index: uav for uav in view.queues for index in view.tour_of(uav)}
    reached = view.reached()
    features = []
    for index, target in enumerate(view.targets.targets):
        uav = reached[index] if index in reached else flyers.get(index)
        if index in reached:
            state, colour = "reached", REACHED_COLOUR
        elif view.team_aborted:
            state, colour = "aborted", UNASSIGNED_COLOUR
        elif uav is not None:
            state, colour = "assigned", colour_of(uav).hex
        else:
            state, colour = "unassigned", UNASSIGNED_COLOUR
        features.append(
            _feature(
                {"type": "Point", "coordinates": [target.lon, target.lat]},
                f"target {index} (mission {view.targets.mission}): {state}"
                + (f" to UAV {uav}" if uav is not None and state == "assigned" else ""),
                colour,
                mission=view.targets.mission,
                target=index,
                alt=target.alt,
                state=state,
                uav=uav,
            )
        )
    return features


def assignment_lines(view: MissionMap) -> list[Feature]:
    """A line from each UAV still flying to its target, in the UAV's colour."""
    if view.targets is None:
        return []
    features = []
    for uav in sorted(view.assigned):
        index = view.target_of(uav)
        position = view.positions.get(uav)
        if index is None or position is None or index in view.reached():
            continue
        if index >= len(view.targets.targets):
            continue  # a report naming a target the mission does not have
        target = view.targets.targets[index]
        features.append(
            _feature(
                {
                    "type": "LineString",
                    "coordinates": [[position[1], position[0]], [target.lon, target.lat]],
                },
                f"UAV {uav} -> target {index}",
                colour_of(uav).hex,
                mission=view.targets.mission,
                target=index,
                uav=uav,
            )
        )
    return features


def tour_lines(view: MissionMap) -> list[Feature]:
    """Each UAV's tour: a line through the rest of its queue,
    from its current target on, in the UAV's colour; none for a queue of one."""
    if view.targets is None:
        return []
    features = []
    for uav, tour in view.tours().items():
        if len(tour) < 2:
            continue
        points = [view.targets.targets[index] for index in tour]
        features.append(
            _feature(
                {"type": "LineString", "coordinates": [[p.lon, p.lat] for p in points]},
                f"UAV {uav} tour: " + " -> ".join(str(index) for index in tour),
                colour_of(uav).hex,
                mission=view.targets.mission,
                uav=uav,
                tour=list(tour),
            )
        )
    return features


#: Drawn in this order; add a layer by adding its function.
LAYERS: tuple[Layer, ...] = (target_points, assignment_lines, tour_lines)


def geojson(view: MissionMap, layers: tuple[Layer, ...] = LAYERS) -> str:
    """The mission as one GeoJSON FeatureCollection (text, as foxglove.GeoJSON carries it)."""
    features = [feature for layer in layers for feature in layer(view)]
    return json.dumps({"type": "FeatureCollection", "features": features})
