"""Simulator scenarios: TOML files naming the aircraft, their start state, plans and wind.

Format (docs/simulator.md has the full description)::

    description = "free text"              # optional
    targets = "head_on_targets.bin"        # optional: a targets file beside this one

    [wind]                                 # optional; the air mass's velocity, m/s
    north = 0.0
    east = 3.0

    [aircraft]                             # optional; the flight envelope of every UAV
    min_airspeed = 15.0                    # m/s
    max_airspeed = 30.0                    # m/s
    bank_limit = 30.0                      # degrees
    roll_rate = 45.0                       # degrees per second
    climb_rate = 3.0                       # m/s
    airspeed_rate = 1.0                    # m/s^2

    [[uav]]
    id = 112                               # Piccolo ID, 1-65520
    lat = 35.72                            # degrees
    lon = -120.79                          # degrees
    alt = 600.0                            # metres
    heading = 90.0                         # degrees true
    airspeed = 22.0                        # m/s
    plan = [[35.72, -120.75, 600.0], ...]  # optional: waypoints 0, 1, ... closed back to 0

Loading is strict: an unknown key is refused (a misspelt `heading` would otherwise
silently mean north), and every error names the file and the field.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from fleet.errors import FleetError
from fleet.geo.aircraft import AircraftLimits
from fleet.mission.messages import Target
from fleet.mission.targets_file import TargetsFileError
from fleet.piccolo.stream_packet import MAX_PICCOLO_ID, MIN_PICCOLO_ID
from fleet.piccolo.waypoint import MAX_INDEX
from fleet.sim.aircraft import Wind
from fleet.sim.uav_spec import UavSpec
from fleet.transport.targets_io import read_targets

__all__ = [
    "Scenario",
    "ScenarioError",
    "load_scenario",
    "parse_scenario",
    "resolve_scenario",
    "shipped_scenario",
    "shipped_scenario_names",
    "shipped_scenario_path",
]

# Mercator degenerates toward the poles; the WAYPOINT packet holds whole metres in an
# i16, and telemetry height is u24 centimetres above -1000 m.
_MAX_ABS_LAT = 85.0
_ALT_RANGE = (-500.0, 10_000.0)

_TOP_KEYS = frozenset({"description", "targets", "wind", "aircraft", "uav"})
_WIND_KEYS = frozenset({"north", "east"})
_AIRCRAFT_KEYS = {
    "min_airspeed": "min_airspeed",
    "max_airspeed": "max_airspeed",
    "bank_limit": "bank_limit_deg",
    "roll_rate": "roll_rate_deg",
    "climb_rate": "climb_rate",
    "airspeed_rate": "airspeed_rate",
}
_UAV_KEYS = frozenset({"id", "lat", "lon", "alt", "heading", "airspeed", "plan"})


class ScenarioError(FleetError, ValueError):
    """A scenario file that cannot be read or does not validate; names file and field."""


@dataclass(frozen=True, slots=True)
class Scenario:
    """A loaded scenario. `targets_path` is resolved against the scenario's directory."""

    name: str
    source: str
    uavs: tuple[UavSpec, ...]
    wind: Wind = field(default_factory=Wind)
    limits: AircraftLimits = field(default_factory=AircraftLimits)
    description: str = ""
    targets_path: Path | None = None

    def uav(self, piccolo_id: int) -> UavSpec:
        for uav in self.uavs:
            if uav.piccolo_id == piccolo_id:
                return uav
        known = ", ".join(str(u.piccolo_id) for u in self.uavs)
        raise ScenarioError(f"{self.source}: no uav with id {piccolo_id} (it has {known})")

    def targets(self) -> list[Target]:
        """The scenario's targets file, read and validated; [] if it names none."""
        if self.targets_path is None:
            return []
        try:
            return read_targets(self.targets_path)
        except (OSError, TargetsFileError) as error:
            raise ScenarioError(f"{self.source}: targets: {error}") from error


def _number(value: Any, where: str, low: float, high: float, *, high_open: bool = False) -> float:
    # bool is an int in Python; `heading = true` is a mistake, not 1 degree.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(f"{where}: expected a number, got {value!r}")
    number = float(value)
    above = number >= high if high_open else number > high
    if not math.isfinite(number) or number < low or above:
        bracket = ")" if high_open else "]"
        raise ScenarioError(
            f"{where}: expected a number in [{low:g}, {high:g}{bracket}, got {value!r}"
        )
    return number


def _table(value: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(value, dict):
        raise ScenarioError(f"{where}: expected a table, got {value!r}")
    return value


def _check_keys(
    table: Mapping[str, Any], allowed: frozenset[str] | Mapping[str, str], where: str
) -> None:
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise ScenarioError(
            f"{where}: unknown key {unknown[0]!r} (expected one of {', '.join(sorted(allowed))})"
        )


def _limits(data: Mapping[str, Any], source: str) -> AircraftLimits:
    if "aircraft" not in data:
        return AircraftLimits()
    table = _table(data["aircraft"], f"{source}: aircraft")
    _check_keys(table, _AIRCRAFT_KEYS, f"{source}: aircraft")
    values = {
        _AIRCRAFT_KEYS[key]: _number(value, f"{source}: aircraft.{key}", 0.0, 1000.0)
        for key, value in table.items()
    }
    try:
        return AircraftLimits(**values)
    except ValueError as error:
        raise ScenarioError(f"{source}: aircraft: {error}") from error


def _wind(data: Mapping[str, Any], source: str, limits: AircraftLimits) -> Wind:
    if "wind" not in data:
        return Wind()
    table = _table(data["wind"], f"{source}: wind")
    _check_keys(table, _WIND_KEYS, f"{source}: wind")
    wind = Wind(
        north=_number(table.get("north", 0.0), f"{source}: wind.north", -100.0, 100.0),
        east=_number(table.get("east", 0.0), f"{source}: wind.east", -100.0, 100.0),
    )
    # An aircraft slower than the wind cannot make way against it; no plan is flyable.
    if wind.speed >= limits.min_airspeed:
        raise ScenarioError(
            f"{source}: wind: speed {wind.speed:.1f} m/s must be below the minimum airspeed "
            f"{limits.min_airspeed:g} m/s"
        )
    return wind


def _plan(value: Any, where: str) -> tuple[tuple[float, float, float], ...]:
    if not isinstance(value, list) or not value:
        raise ScenarioError(f"{where}: expected a non-empty list of [lat, lon, alt]")
    if len(value) > MAX_INDEX + 1:
        raise ScenarioError(f"{where}: {len(value)} waypoints; at most {MAX_INDEX + 1} fit (0-99)")
    points = []
    for i, point in enumerate(value):
        here = f"{where}[{i}]"
        if not isinstance(point, list) or len(point) != 3:
            raise ScenarioError(f"{here}: expected [lat, lon, alt], got {point!r}")
        points.append(
            (
                _number(point[0], f"{here}.lat", -_MAX_ABS_LAT, _MAX_ABS_LAT),
                _number(point[1], f"{here}.lon", -180.0, 180.0),
                _number(point[2], f"{here}.alt", *_ALT_RANGE),
            )
        )
    return tuple(points)


def _uav(value: Any, where: str, limits: AircraftLimits) -> UavSpec:
    table = _table(value, where)
    _check_keys(table, _UAV_KEYS, where)
    for key in ("id", "lat", "lon", "alt", "heading", "airspeed"):
        if key not in table:
            raise ScenarioError(f"{where}: missing required key {key!r}")
    piccolo_id = table["id"]
    if (
        isinstance(piccolo_id, bool)
        or not isinstance(piccolo_id, int)
        or not MIN_PICCOLO_ID <= piccolo_id <= MAX_PICCOLO_ID
    ):
        raise ScenarioError(
            f"{where}.id: expected a Piccolo ID, an integer in "
            f"[{MIN_PICCOLO_ID}, {MAX_PICCOLO_ID}], got {piccolo_id!r}"
        )
    return UavSpec(
        piccolo_id=piccolo_id,
        lat=_number(table["lat"], f"{where}.lat", -_MAX_ABS_LAT, _MAX_ABS_LAT),
        lon=_number(table["lon"], f"{where}.lon", -180.0, 180.0),
        alt=_number(table["alt"], f"{where}.alt", *_ALT_RANGE),
        heading=_number(table["heading"], f"{where}.heading", 0.0, 360.0, high_open=True),
        airspeed=_number(
            table["airspeed"], f"{where}.airspeed", limits.min_airspeed, limits.max_airspeed
        ),
        plan=_plan(table["plan"], f"{where}.plan") if "plan" in table else None,
    )


def parse_scenario(
    data: Mapping[str, Any], source: str, base_dir: Path | None = None, name: str = ""
) -> Scenario:
    """Validate parsed TOML. `source` names the file in errors; `base_dir` resolves
    the targets file (the current directory if None)."""
    _check_keys(data, _TOP_KEYS, source)
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ScenarioError(f"{source}: description: expected a string, got {description!r}")
    limits = _limits(data, source)
    wind = _wind(data, source, limits)

    targets_path = None
    if "targets" in data:
        targets = data["targets"]
        if not isinstance(targets, str) or not targets:
            raise ScenarioError(f"{source}: targets: expected a file name, got {targets!r}")
        targets_path = (base_dir or Path.cwd()) / targets
        if not targets_path.is_file():
            raise ScenarioError(f"{source}: targets: no such file {str(targets_path)!r}")

    uav_list = data.get("uav")
    if not isinstance(uav_list, list) or not uav_list:
        raise ScenarioError(f"{source}: uav: expected at least one [[uav]] table")
    uavs: list[UavSpec] = []
    for i, value in enumerate(uav_list):
        uav = _uav(value, f"{source}: uav[{i}]", limits)
        if any(other.piccolo_id == uav.piccolo_id for other in uavs):
            raise ScenarioError(f"{source}: uav[{i}].id: Piccolo ID {uav.piccolo_id} repeated")
        uavs.append(uav)
    return Scenario(
        name=name,
        source=source,
        uavs=tuple(uavs),
        wind=wind,
        limits=limits,
        description=description,
        targets_path=targets_path,
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; raises ScenarioError naming file and field."""
    path = Path(path)
    source = str(path)
    try:
        with path.open("rb") as file:
            data = tomllib.load(file)
    except OSError as error:
        raise ScenarioError(f"{source}: cannot read: {error.strerror or error}") from error
    except tomllib.TOMLDecodeError as error:
        raise ScenarioError(f"{source}: not valid TOML: {error}") from error
    return parse_scenario(data, source, path.parent, path.stem)


def _shipped_dir() -> Path:
    directory = resources.files("fleet") / "scenarios"
    # The package is installed as plain files (setuptools, editable or not); a zipped
    # install would need resources.as_file, which the targets-file path cannot outlive.
    if not isinstance(directory, Path):
        raise ScenarioError(f"shipped scenarios are not on the file system ({directory})")
    return directory


def shipped_scenario_names() -> list[str]:
    """Names of the scenarios shipped in `fleet/scenarios`, sorted."""
    return sorted(path.stem for path in _shipped_dir().glob("*.toml"))


def shipped_scenario_path(name: str) -> Path:
    path = _shipped_dir() / f"{name}.toml"
    if not path.is_file():
        raise ScenarioError(
            f"no shipped scenario {name!r} (shipped: {', '.join(shipped_scenario_names())})"
        )
    return path


def shipped_scenario(name: str) -> Scenario:
    """A shipped scenario by name, e.g. "single_uav" or "head_on"."""
    return load_scenario(shipped_scenario_path(name))


def resolve_scenario(name_or_path: str) -> Scenario:
    """A scenario file if `name_or_path` is an existing file or ends in .toml, else the
    shipped scenario of that name."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.is_file() or len(path.parts) > 1:
        return load_scenario(path)
    return shipped_scenario(name_or_path)
