"""What `fleet foxglove` shows in Foxglove's 3D and Log panels.

* `{prefix}/scene`: a `foxglove.SceneUpdate` of the fleet in one frame, `fleet`: east,
  north and up in metres from an origin fixed when the scene is first drawn (the first
  UAV's position, or the mission's first target). Each UAV an arrow along its heading
  at its altitude with its Piccolo ID above it, in its colour (the page's); each target
  of the mission a sphere coloured by its state with its index; each UAV's tour a line
  from the UAV through the targets it still has to fly; each no-fly zone its outline
  and name, on the ground and at the UAVs' altitude. Every update replaces the whole
  scene (a deletion of everything first), so nothing of an older mission stays.
* `{prefix}/log`: each UAV's status text as a `foxglove.Log`, its level the message's
  severity and its name the UAV's.

The scene is computed as plain `Shape`s (pure, `Scene.shapes`), then made into the
SDK's messages (`scene_update`), which can be built but not read back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from foxglove.messages import (
    ArrowPrimitive,
    Color,
    LinePrimitive,
    LinePrimitiveLineType,
    Log,
    LogLevel,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from fleet.geo.mercator import MercatorProjection
from ground.foxglove_live.map_layers import (
    REACHED_COLOUR,
    UNASSIGNED_COLOUR,
    MissionMap,
    Rgb,
    colour_of,
)

SCENE_TOPIC_LEAF = "scene"
LOG_TOPIC_LEAF = "log"
#: The scene's one frame: east, north, up (m) from the origin.
FRAME = "fleet"
#: Sizes in metres: seen from a few kilometres, as the fleet's distances are.
UAV_LENGTH_M = 120.0
TARGET_SIZE_M = 80.0
LABEL_PX = 14.0  #: labels keep their size as the view zooms
LINE_PX = 2.0
_LEVELS = {"info": LogLevel.Info, "warning": LogLevel.Warning, "error": LogLevel.Error}

Point = tuple[float, float, float]


def scene_topic(prefix: str) -> str:
    return f"{prefix}/{SCENE_TOPIC_LEAF}"


def log_topic(prefix: str) -> str:
    return f"{prefix}/{LOG_TOPIC_LEAF}"


def timestamp(time_ns: int) -> Timestamp:
    return Timestamp(time_ns // 1_000_000_000, time_ns % 1_000_000_000)


# ---- the Log panel ---------------------------------------------------------------------------
def log_level(status: object) -> LogLevel | None:
    """The Log level of a status text (as JSON); None if it is not one."""
    if not isinstance(status, dict) or not isinstance(status.get("text"), str):
        return None
    return _LEVELS.get(str(status.get("severity", "info")), LogLevel.Info)


def status_log(status: object, uav: int, time_ns: int) -> Log | None:
    """A status text (as JSON) as a Log; None if it is not one."""
    level = log_level(status)
    if level is None or not isinstance(status, dict):
        return None
    return Log(timestamp=timestamp(time_ns), level=level, message=status["text"], name=f"uav{uav}")


# ---- the 3D panel ----------------------------------------------------------------------------
class ShapeKind(Enum):
    UAV = "uav"  #: an arrow at `points[0]` along `heading_rad`
    TARGET = "target"  #: a sphere at `points[0]`
    TOUR = "tour"  #: a line through `points`
    ZONE = "zone"  #: a closed line through `points`, on the ground and at `points`' height


@dataclass(frozen=True)
class Shape:
    """One entity of the scene: its id, kind, points (m), colour and label."""

    entity_id: str
    kind: ShapeKind
    points: tuple[Point, ...]
    colour: Rgb
    label: str = ""
    heading_rad: float = 0.0  #: clockwise from north
    alpha: float = 1.0


def _rgb(text: str) -> Rgb:
    r, g, b = (int(text[i : i + 2], 16) / 255.0 for i in (1, 3, 5))
    return Rgb(r, g, b)


class Scene:
    """The fleet's 3D scene from a `MissionMap`, in metres from an origin fixed once."""

    def __init__(self) -> None:
        self.projection: MercatorProjection | None = None

    def _origin(self, view: MissionMap) -> MercatorProjection | None:
        if self.projection is None:
            if view.fixes:
                fix = view.fixes[min(view.fixes)]
                self.projection = MercatorProjection(fix.latitude, fix.longitude)
            elif view.targets is not None and view.targets.targets:
                first = view.targets.targets[0]
                self.projection = MercatorProjection(first.lat, first.lon)
        return self.projection

    def shapes(self, view: MissionMap) -> list[Shape] | None:
        """The whole scene now; None while there is nothing to place it by."""
        projection = self._origin(view)
        if projection is None:
            return None
        return [
            *_uavs(view, projection),
            *_targets(view, projection),
            *_tours(view, projection),
            *_zones(view, projection),
        ]

    def update(self, view: MissionMap, time_ns: int) -> SceneUpdate | None:
        shapes = self.shapes(view)
        return None if shapes is None else scene_update(shapes, time_ns)


def _uavs(view: MissionMap, projection: MercatorProjection) -> list[Shape]:
    found = []
    for uav, fix in sorted(view.fixes.items()):
        x, y = projection.to_xy(fix.latitude, fix.longitude)
        found.append(
            Shape(
                f"uav/{uav}",
                ShapeKind.UAV,
                ((x, y, fix.altitude),),
                fix.colour,
                f"UAV {uav}",
                heading_rad=fix.heading_rad or 0.0,
            )
        )
    return found


def _targets(view: MissionMap, projection: MercatorProjection) -> list[Shape]:
    if view.targets is None:
        return []
    reached = view.reached()
    flyers = {index: uav for uav in view.queues for index in view.tour_of(uav)}
    found = []
    for index, target in enumerate(view.targets.targets):
        x, y = projection.to_xy(target.lat, target.lon)
        if index in reached:
            colour = _rgb(REACHED_COLOUR)
        elif index in flyers and not view.team_aborted:
            colour = colour_of(flyers[index])
        else:
            colour = _rgb(UNASSIGNED_COLOUR)
        entity_id = f"target/{view.targets.mission}/{index}"
        found.append(
            Shape(entity_id, ShapeKind.TARGET, ((x, y, target.alt),), colour, f"target {index}")
        )
    return found


def _tours(view: MissionMap, projection: MercatorProjection) -> list[Shape]:
    """From each UAV through the targets it still has to fly, in its colour."""
    if view.targets is None:
        return []
    found = []
    for uav, tour in view.tours().items():
        fix = view.fixes.get(uav)
        if not tour or fix is None:
            continue
        x, y = projection.to_xy(fix.latitude, fix.longitude)
        points = [(x, y, fix.altitude)]
        for index in tour:
            target = view.targets.targets[index]
            x, y = projection.to_xy(target.lat, target.lon)
            points.append((x, y, target.alt))
        found.append(Shape(f"tour/{uav}", ShapeKind.TOUR, tuple(points), colour_of(uav), alpha=0.8))
    return found


def _zones(view: MissionMap, projection: MercatorProjection) -> list[Shape]:
    """Each no-fly zone's outline, as high as the UAVs fly, with its name."""
    if view.targets is None:
        return []
    ceiling = max((fix.altitude for fix in view.fixes.values()), default=0.0)
    if not ceiling:
        ceiling = max((t.alt for t in view.targets.targets), default=0.0)
    found = []
    for index, zone in enumerate(view.targets.zones):
        corners = tuple((*projection.to_xy(lat, lon), ceiling) for lat, lon in zone.ring)
        entity_id = f"zone/{view.targets.mission}/{index}"
        name = zone.name or f"zone {index}"
        found.append(
            Shape(entity_id, ShapeKind.ZONE, corners, _rgb(UNASSIGNED_COLOUR), name, alpha=0.9)
        )
    return found


# ---- the SDK's messages ----------------------------------------------------------------------
def _colour(rgb: Rgb, alpha: float) -> Color:
    return Color(r=rgb.r, g=rgb.g, b=rgb.b, a=alpha)


def _pose(x: float, y: float, z: float, yaw: float = 0.0) -> Pose:
    """At (x, y, z), turned `yaw` radians anticlockwise about up."""
    return Pose(
        position=Vector3(x=x, y=y, z=z),
        orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )


def _line(points: tuple[Point, ...], colour: Color) -> LinePrimitive:
    return LinePrimitive(
        type=LinePrimitiveLineType.LineStrip,
        pose=_pose(0.0, 0.0, 0.0),
        thickness=LINE_PX,
        scale_invariant=True,
        points=[Point3(x=x, y=y, z=z) for x, y, z in points],
        color=colour,
    )


def _entity(shape: Shape, stamp: Timestamp) -> SceneEntity:
    colour = _colour(shape.colour, shape.alpha)
    x, y, z = shape.points[0]
    above = UAV_LENGTH_M if shape.kind is ShapeKind.UAV else TARGET_SIZE_M
    label = TextPrimitive(
        pose=_pose(x, y, z + above),
        billboard=True,
        font_size=LABEL_PX,
        scale_invariant=True,
        color=colour,
        text=shape.label,
    )
    texts = [label] if shape.label else []

    def entity(
        arrows: list[ArrowPrimitive] | None = None,
        spheres: list[SpherePrimitive] | None = None,
        lines: list[LinePrimitive] | None = None,
    ) -> SceneEntity:
        return SceneEntity(
            timestamp=stamp,
            frame_id=FRAME,
            id=shape.entity_id,
            texts=texts,
            arrows=arrows,
            spheres=spheres,
            lines=lines,
        )

    if shape.kind is ShapeKind.UAV:
        # An arrow points along its x axis (east): turned to the compass heading.
        arrow = ArrowPrimitive(
            pose=_pose(x, y, z, math.pi / 2 - shape.heading_rad),
            shaft_length=UAV_LENGTH_M * 0.6,
            shaft_diameter=UAV_LENGTH_M * 0.15,
            head_length=UAV_LENGTH_M * 0.4,
            head_diameter=UAV_LENGTH_M * 0.45,
            color=colour,
        )
        return entity(arrows=[arrow])
    if shape.kind is ShapeKind.TARGET:
        size = Vector3(x=TARGET_SIZE_M, y=TARGET_SIZE_M, z=TARGET_SIZE_M)
        return entity(spheres=[SpherePrimitive(pose=_pose(x, y, z), size=size, color=colour)])
    if shape.kind is ShapeKind.ZONE:
        ground = tuple((px, py, 0.0) for px, py, _ in shape.points)
        return entity(lines=[_line(ground, colour), _line(shape.points, colour)])
    return entity(lines=[_line(shape.points, colour)])


def scene_update(shapes: list[Shape], time_ns: int) -> SceneUpdate:
    """The SDK's SceneUpdate: everything deleted, then every shape."""
    stamp = timestamp(time_ns)
    everything = SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletionType.All)
    return SceneUpdate(deletions=[everything], entities=[_entity(s, stamp) for s in shapes])
