"""Load/Save Targets in CSV and GeoJSON: round trips, and refusals that say where and why."""

from __future__ import annotations

import json

import pytest

from fleet.mission.messages import Target
from fleet.mission.targets_file import encode_targets
from ground import targets_formats
from ground.targets_formats import TargetsFormat, TargetsFormatError, decode, encode, format_of

TARGETS = [Target(35.72, -120.765, 600.0), Target(35.7, -120.7, 550.5)]


@pytest.mark.parametrize("fmt", list(TargetsFormat))
def test_every_format_round_trips(fmt: TargetsFormat) -> None:
    assert decode(encode(TARGETS, fmt), f"t.{fmt}", fmt) == TARGETS


def test_the_format_follows_the_extension() -> None:
    assert format_of("a.CSV") is TargetsFormat.CSV
    assert format_of("a.geojson") is TargetsFormat.GEOJSON
    assert format_of("a.json") is TargetsFormat.GEOJSON
    assert format_of("targets.bin") is TargetsFormat.BINARY
    assert decode(encode_targets(TARGETS), "targets.bin") == TARGETS


def test_csv_with_or_without_header_and_blank_lines() -> None:
    text = b"35.72,-120.765,600\n\n35.7, -120.7 ,550.5\n"
    assert decode(text, "t.csv") == TARGETS
    assert decode(b"lat,lon,alt\n" + text, "t.csv") == TARGETS


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"35.72,-120.765\n", r"t\.csv: line 1: 2 fields, expected 3"),
        (b"lat,lon,alt\n35.72,east,600\n", r"t\.csv: line 2: lon 'east' is not a number"),
        (b"35.72,-120.765,nan\n", r"line 1: alt 'nan' is not a finite number"),
        (b"95,-120.765,600\n", r"t\.csv: target 0: latitude 95\.0 is outside \[-90, 90\]"),
        (b"lat,lon,alt\n", r"t\.csv: no targets"),
        (b"\xff\xfe", r"t\.csv: not UTF-8 text at byte 0"),
    ],
)
def test_malformed_csv_is_refused(data: bytes, match: str) -> None:
    with pytest.raises(TargetsFormatError, match=match):
        decode(data, "t.csv")


def _point(coordinates: list[object], **properties: object) -> dict[str, object]:
    return {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": coordinates},
        "properties": properties,
    }


def test_geojson_altitude_may_be_a_property() -> None:
    document = {"type": "FeatureCollection", "features": [_point([-120.765, 35.72], alt=600)]}
    assert decode(json.dumps(document).encode(), "t.geojson") == [TARGETS[0]]


@pytest.mark.parametrize(
    ("document", "match"),
    [
        ("{", r"t\.geojson: not JSON"),
        ('{"type": "Feature"}', r"expected a GeoJSON FeatureCollection"),
        (
            {"type": "FeatureCollection", "features": [_point([-120.7, 35.7])]},
            r"feature 0: no altitude",
        ),
        (
            {"type": "FeatureCollection", "features": [_point([-120.7, "x", 5])]},
            r"feature 0: lat 'x' is not a number",
        ),
        (
            {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": None}]},
            r"feature 0: expected a Point geometry",
        ),
        (
            {"type": "FeatureCollection", "features": [_point([-200.0, 35.7, 5])]},
            r"target 0: longitude -200\.0 is outside",
        ),
    ],
)
def test_malformed_geojson_is_refused(document: object, match: str) -> None:
    data = document if isinstance(document, str) else json.dumps(document)
    with pytest.raises(TargetsFormatError, match=match):
        decode(data.encode(), "t.geojson")


def test_a_truncated_binary_file_is_refused_with_the_codecs_message() -> None:
    with pytest.raises(TargetsFormatError, match=r"bad\.bin: target 1 at byte offset 24"):
        decode(b"\x00" * 25, "bad.bin")


def test_nothing_unreadable_is_written() -> None:
    with pytest.raises(TargetsFormatError, match="no targets"):
        encode([], TargetsFormat.CSV)
    with pytest.raises(
        TargetsFormatError, match="target 0: latitude is inf, expected a finite number"
    ):
        encode([Target(float("inf"), 0.0, 0.0)], targets_formats.TargetsFormat.GEOJSON)


def test_a_deeply_nested_geojson_is_refused_not_a_crash() -> None:
    with pytest.raises(TargetsFormatError, match=r"deep\.geojson: nested too deeply"):
        decode(b"[" * 100_000 + b"]" * 100_000, "deep.geojson")
