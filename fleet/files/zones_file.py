"""No-fly zones in and out of GeoJSON files (`send-targets --no-fly`, the page, the
simulator's `--no-fly`).

A zones file is a GeoJSON FeatureCollection (or a single Feature, or a bare geometry)
of `Polygon` and `MultiPolygon` geometries in WGS-84 [longitude, latitude] order; a
feature's `name` property names its zone. Every ring must be closed (its last position
its first, as GeoJSON requires); a polygon with holes is refused, since a zone is flown
around as a whole. The file is read as hostile input: the JSON loading is the targets
files' (`fleet.files.geojson.load_json`), each value is checked before use, and each
zone's shape is checked as every UAV will check it (`fleet.mission.no_fly`). Every
refusal is a `ZonesFileError` naming the file, the feature and what was expected.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from typing import Any

from fleet.errors import CodecError
from fleet.files.geojson import load_json
from fleet.mission.messages import MAX_ZONE_RING, MAX_ZONES, NoFlyZone
from fleet.mission.no_fly import mission_zone_problem

__all__ = ["ZonesFileError", "decode_zones", "encode_zones", "read_zones"]


class ZonesFileError(CodecError):
    """A zones file that is malformed, or a zone that is not usable; says where and why."""


_NAME_LIMIT = 64


def _position(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) not in (2, 3):
        raise ZonesFileError(f"{where}: expected a position [lon, lat]")
    for name, number in zip(("lon", "lat"), value[:2], strict=True):
        if isinstance(number, bool) or not isinstance(number, int | float):
            raise ZonesFileError(f"{where}: {name} {number!r} is not a number")
        if not math.isfinite(number):
            raise ZonesFileError(f"{where}: {name} is not a finite number")
    lon, lat = float(value[0]), float(value[1])
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ZonesFileError(f"{where}: [{lon}, {lat}] is not a longitude and latitude")
    return lat, lon


def _polygon(rings: Any, name: str, where: str) -> NoFlyZone:
    if not isinstance(rings, list) or not rings:
        raise ZonesFileError(f"{where}: expected a Polygon's list of rings")
    if len(rings) > 1:
        raise ZonesFileError(
            f"{where}: a polygon with {len(rings) - 1} hole(s): a zone is one ring, no holes"
        )
    ring = rings[0]
    if not isinstance(ring, list) or len(ring) > MAX_ZONE_RING:
        size = len(ring) if isinstance(ring, list) else "no"
        raise ZonesFileError(
            f"{where}: {size} positions in the ring, expected 4 to {MAX_ZONE_RING}"
        )
    points = tuple(_position(p, f"{where}: position {i}") for i, p in enumerate(ring))
    if len(points) < 4 or points[0] != points[-1]:
        raise ZonesFileError(
            f"{where}: the ring is not closed (GeoJSON: at least 4 positions, the last "
            "one the first)"
        )
    return NoFlyZone(ring=points, name=name)


def _name(feature: dict[str, Any]) -> str:
    properties = feature.get("properties")
    name = properties.get("name") if isinstance(properties, dict) else None
    return name[:_NAME_LIMIT] if isinstance(name, str) else ""


def _zones_of(geometry: Any, name: str, where: str) -> list[NoFlyZone]:
    if not isinstance(geometry, dict):
        raise ZonesFileError(f"{where}: expected a geometry object")
    kind, coordinates = geometry.get("type"), geometry.get("coordinates")
    if kind == "Polygon":
        return [_polygon(coordinates, name, where)]
    if kind == "MultiPolygon" and isinstance(coordinates, list):
        if len(coordinates) > MAX_ZONES:
            raise ZonesFileError(f"{where}: more than {MAX_ZONES} polygons")
        return [_polygon(p, name, f"{where}: polygon {i}") for i, p in enumerate(coordinates)]
    raise ZonesFileError(f"{where}: expected a Polygon or MultiPolygon geometry")


def decode_zones(data: bytes, source: str) -> tuple[NoFlyZone, ...]:
    """The zones of a GeoJSON file; ZonesFileError says where and why not."""
    document = load_json(data, source, ZonesFileError)
    if not isinstance(document, dict):
        raise ZonesFileError(f"{source}: expected a GeoJSON object of Polygons")
    if document.get("type") == "FeatureCollection":
        features = document.get("features")
        if not isinstance(features, list):
            raise ZonesFileError(f"{source}: expected a list of features")
    else:
        features = [document]
    if len(features) > MAX_ZONES:
        raise ZonesFileError(f"{source}: {len(features)} features, at most {MAX_ZONES}")
    zones: list[NoFlyZone] = []
    for i, feature in enumerate(features):
        where = f"{source}: feature {i}"
        if isinstance(feature, dict) and feature.get("type") == "Feature":
            zones += _zones_of(feature.get("geometry"), _name(feature), where)
        else:
            zones += _zones_of(feature, "", where)
        if len(zones) > MAX_ZONES:
            raise ZonesFileError(f"{source}: more than {MAX_ZONES} zones")
    problem = mission_zone_problem(zones)
    if problem is not None:
        raise ZonesFileError(f"{source}: {problem}")
    return tuple(zones)


def read_zones(path: str | os.PathLike[str]) -> tuple[NoFlyZone, ...]:
    """The zones of a GeoJSON file on disk (ZonesFileError, OSError)."""
    with open(path, "rb") as f:
        return decode_zones(f.read(), os.fspath(path))


def encode_zones(zones: Sequence[NoFlyZone]) -> bytes:
    """A GeoJSON FeatureCollection of one Polygon per zone (closed rings)."""
    features = []
    for zone in zones:
        ring = [[lon, lat] for lat, lon in zone.ring]
        if ring and ring[0] != ring[-1]:
            ring.append(ring[0])
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": [ring]},
                "properties": {"name": zone.name},
            }
        )
    return json.dumps({"type": "FeatureCollection", "features": features}, indent=1).encode()
