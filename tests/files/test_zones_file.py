"""Tests of no-fly zones in GeoJSON (fleet.files.zones_file): read back what is written,
and every malformed or hostile file refused by name."""

from __future__ import annotations

import json
from typing import Any

import pytest

from fleet.files.zones_file import ZonesFileError, decode_zones, encode_zones
from fleet.mission.messages import NoFlyZone

SQUARE = [[-71.10, 42.35], [-71.09, 42.35], [-71.09, 42.36], [-71.10, 42.36], [-71.10, 42.35]]


def polygon(ring: list[list[Any]], name: str = "town") -> dict[str, Any]:
    return {
        "type": "Feature",
        "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {"name": name},
    }


def collection(*features: Any) -> bytes:
    return json.dumps({"type": "FeatureCollection", "features": list(features)}).encode()


def test_a_polygon_is_read_as_a_named_zone_of_lat_lon_vertices() -> None:
    (zone,) = decode_zones(collection(polygon(SQUARE)), "z.geojson")
    assert zone.name == "town"
    assert zone.ring[0] == (42.35, -71.10)
    assert len(zone.ring) == 5


def test_a_multipolygon_and_a_bare_geometry_are_read() -> None:
    shifted = [[lon + 0.05, lat] for lon, lat in SQUARE]
    multi = {"type": "MultiPolygon", "coordinates": [[SQUARE], [shifted]]}
    assert len(decode_zones(json.dumps(multi).encode(), "z.json")) == 2
    assert len(decode_zones(collection(polygon(SQUARE), multi), "z.json")) == 3


def test_zones_written_are_read_back() -> None:
    zones = decode_zones(collection(polygon(SQUARE)), "z.geojson")
    assert decode_zones(encode_zones(zones), "again.geojson") == zones
    open_ring = NoFlyZone(ring=tuple((lat, lon) for lon, lat in SQUARE[:-1]))
    assert len(decode_zones(encode_zones([open_ring]), "o.geojson")[0].ring) == 5


@pytest.mark.parametrize(
    ("data", "where"),
    [
        (b"{", "not JSON"),
        (b"[" * 100_000, "nested too deeply"),
        (b"[]", "expected a GeoJSON object"),
        (collection(polygon(SQUARE[:-1])), "feature 0: the ring is not closed"),
        (collection(polygon([[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]])), "cross"),
        (collection(polygon([[-71.1, "x"], *SQUARE[1:]])), "lat 'x' is not a number"),
        (collection(polygon([[-71.1, 95.0], *SQUARE[1:]])), "is not a longitude and latitude"),
        (collection({"type": "Feature", "geometry": {"type": "Point"}}), "Polygon or Multi"),
        (
            json.dumps({"type": "Polygon", "coordinates": [SQUARE, SQUARE]}).encode(),
            "hole",
        ),
        (collection(polygon([[-71.1 + i * 1e-4, 42.35] for i in range(70)])), "positions"),
        (collection(*[polygon(SQUARE)] * 17), "at most 16"),
    ],
)
def test_a_bad_zones_file_is_refused_by_name(data: bytes, where: str) -> None:
    with pytest.raises(ZonesFileError, match=r"zones\.geojson") as caught:
        decode_zones(data, "zones.geojson")
    assert where in str(caught.value)
