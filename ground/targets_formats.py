"""Targets in and out of files: the thesis's binary format, CSV and GeoJSON.

The binary format is `fleet.mission.targets_file`'s (24 bytes a target); CSV and
GeoJSON are for other tools (spreadsheets, GIS). Whatever the format, every target goes
through the binary codec's validation (finite, latitude and longitude in range), so a
file is accepted by one format exactly when its targets could be sent. Every refusal is
a `TargetsFormatError` naming the file, the place in it (line, feature or target) and
what was expected.
"""

from __future__ import annotations

import csv
import io
import json
import math
from enum import StrEnum
from typing import Any

from fleet.errors import CodecError
from fleet.files.geojson import load_json
from fleet.mission.messages import Target
from fleet.mission.targets_file import TargetsFileError, decode_targets, encode_targets

#: The CSV header written, and accepted (optionally) as a file's first row.
CSV_HEADER = ("lat", "lon", "alt")


class TargetsFormat(StrEnum):
    BINARY = "bin"
    CSV = "csv"
    GEOJSON = "geojson"


MEDIA_TYPES = {
    TargetsFormat.BINARY: "application/octet-stream",
    TargetsFormat.CSV: "text/csv",
    TargetsFormat.GEOJSON: "application/geo+json",
}


class TargetsFormatError(CodecError):
    """A targets file (or a target list to write) that is malformed; says where and why."""


def format_of(name: str) -> TargetsFormat:
    """The format a file name implies: .csv, .geojson/.json, anything else binary."""
    lower = name.lower()
    if lower.endswith(".csv"):
        return TargetsFormat.CSV
    if lower.endswith((".geojson", ".json")):
        return TargetsFormat.GEOJSON
    return TargetsFormat.BINARY


def _checked(targets: list[Target], source: str) -> list[Target]:
    """`targets` if the binary codec would accept them; else which one and why."""
    try:
        encode_targets(targets, source=source)
    except TargetsFileError as error:
        if not targets:
            raise TargetsFormatError(f"{source}: no targets: expected at least one") from None
        raise TargetsFormatError(f"{source}: target {error.index}: {error.problem}") from None
    return targets


def _number(text: str, what: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TargetsFormatError(f"{where}: {what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise TargetsFormatError(f"{where}: {what} {text!r} is not a finite number")
    return value


def decode_csv(data: bytes, source: str) -> list[Target]:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise TargetsFormatError(
            f"{source}: not UTF-8 text at byte {error.start}: expected CSV rows lat,lon,alt"
        ) from None
    targets = []
    for number, row in enumerate(csv.reader(io.StringIO(text)), start=1):
        cells = [cell.strip() for cell in row]
        if not any(cells):
            continue
        if number == 1 and tuple(c.lower() for c in cells) == CSV_HEADER:
            continue
        where = f"{source}: line {number}"
        if len(cells) != 3:
            raise TargetsFormatError(
                f"{where}: {len(cells)} fields, expected 3 (lat,lon,alt in degrees, "
                "degrees, metres)"
            )
        lat, lon, alt = (_number(c, n, where) for c, n in zip(cells, CSV_HEADER, strict=True))
        targets.append(Target(lat=lat, lon=lon, alt=alt))
    return _checked(targets, source)


def encode_csv(targets: list[Target]) -> bytes:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_HEADER)
    for target in targets:
        writer.writerow((repr(target.lat), repr(target.lon), repr(target.alt)))
    return out.getvalue().encode()


def _geojson_target(feature: Any, where: str) -> Target:
    if not isinstance(feature, dict) or feature.get("type") != "Feature":
        raise TargetsFormatError(f"{where}: expected a GeoJSON Feature object")
    geometry = feature.get("geometry")
    if not isinstance(geometry, dict) or geometry.get("type") != "Point":
        raise TargetsFormatError(f"{where}: expected a Point geometry")
    coordinates = geometry.get("coordinates")
    if not isinstance(coordinates, list) or len(coordinates) not in (2, 3):
        raise TargetsFormatError(f"{where}: expected coordinates [lon, lat, alt]")
    properties = feature.get("properties") or {}
    alt = coordinates[2] if len(coordinates) == 3 else properties.get("alt")
    if alt is None:
        raise TargetsFormatError(
            f"{where}: no altitude: expected coordinates [lon, lat, alt] or a property alt"
        )
    values = (coordinates[1], coordinates[0], alt)
    for name, value in zip(CSV_HEADER, values, strict=True):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TargetsFormatError(f"{where}: {name} {value!r} is not a number")
    return Target(lat=float(values[0]), lon=float(values[1]), alt=float(values[2]))


def decode_geojson(data: bytes, source: str) -> list[Target]:
    document = load_json(data, source, TargetsFormatError)
    if not isinstance(document, dict) or document.get("type") != "FeatureCollection":
        raise TargetsFormatError(f"{source}: expected a GeoJSON FeatureCollection of Points")
    features = document.get("features")
    if not isinstance(features, list):
        raise TargetsFormatError(f"{source}: expected a list of features")
    targets = [
        _geojson_target(feature, f"{source}: feature {i}") for i, feature in enumerate(features)
    ]
    return _checked(targets, source)


def encode_geojson(targets: list[Target]) -> bytes:
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [t.lon, t.lat, t.alt]},
            "properties": {"index": i, "alt": t.alt},
        }
        for i, t in enumerate(targets)
    ]
    return json.dumps({"type": "FeatureCollection", "features": features}, indent=1).encode()


def decode(data: bytes, source: str, fmt: TargetsFormat | None = None) -> list[Target]:
    """Targets from a file's bytes, in `fmt` (default: from `source`'s extension)."""
    fmt = fmt or format_of(source)
    if fmt is TargetsFormat.CSV:
        return decode_csv(data, source)
    if fmt is TargetsFormat.GEOJSON:
        return decode_geojson(data, source)
    try:
        return decode_targets(data, source)
    except TargetsFileError as error:
        raise TargetsFormatError(str(error)) from None


def encode(targets: list[Target], fmt: TargetsFormat) -> bytes:
    """A file's bytes; refuses (TargetsFormatError) what could not be read back."""
    _checked(targets, "<targets>")
    if fmt is TargetsFormat.CSV:
        return encode_csv(targets)
    if fmt is TargetsFormat.GEOJSON:
        return encode_geojson(targets)
    return encode_targets(targets)
