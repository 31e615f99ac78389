"""Simulator scenarios: TOML files naming the aircraft, their start state, plans and wind.

Format (docs/simulator.md has the full description)::

    description = "free text"              # optional
    targets = "head_on_targets.bin"        # optional: a targets file beside this one
    no_fly = "zones.geojson"               # optional: no-fly zones whose incursions are logged

    [wind]                                 # optional; the air mass's velocity, m/s
    north = 0.0
    east = 3.0
    drift_speed = 1.0                      # optional weather (fleet.sim.weather):
    drift_direction = 10.0                 #   slow drift (m/s, degrees) over
    drift_period = 1800.0                  #   this period (s),
    gust = 1.5                             #   gusts (m/s, standard deviation)
    gust_time = 5.0                        #   lasting this long (s),
    estimate_lag = 10.0                    #   the reported estimate's lag (s)
    estimate_error = 0.5                   #   and bias (m/s, standard deviation),
    seed = 0                               #   all drawn from this seed

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

Loading is strict (`msgspec.toml` against the file's schema below): an unknown key, a
wrong type or a number out of range is refused, and every error names the file and the
field.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Annotated

import msgspec

from fleet.errors import FleetError
from fleet.files.targets_io import read_targets
from fleet.files.zones_file import ZonesFileError, read_zones
from fleet.geo.aircraft import AircraftLimits
from fleet.mission.messages import NoFlyZone, Target
from fleet.mission.targets_file import TargetsFileError
from fleet.piccolo.stream_packet import MAX_PICCOLO_ID, MIN_PICCOLO_ID
from fleet.piccolo.waypoint import MAX_INDEX
from fleet.sim.aircraft import Wind
from fleet.sim.uav_spec import UavSpec
from fleet.sim.weather import WeatherSpec

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
_Lat = Annotated[float, msgspec.Meta(ge=-85.0, le=85.0)]
_Lon = Annotated[float, msgspec.Meta(ge=-180.0, le=180.0)]
_Alt = Annotated[float, msgspec.Meta(ge=-500.0, le=10_000.0)]
_WindSpeed = Annotated[float, msgspec.Meta(ge=-100.0, le=100.0)]
_Limit = Annotated[float, msgspec.Meta(ge=0.0, le=1000.0)]


# The file's schema: msgspec refuses unknown keys (a misspelt `heading` would otherwise
# silently mean north), wrong types (`heading = true` is a mistake, not 1 degree), NaN
# and out-of-range numbers, and names the field in its error.
_Positive = Annotated[float, msgspec.Meta(gt=0.0, le=1e6)]


class _WindTable(msgspec.Struct, forbid_unknown_fields=True):
    north: _WindSpeed = 0.0
    east: _WindSpeed = 0.0
    drift_speed: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)] = 0.0
    drift_direction: Annotated[float, msgspec.Meta(ge=0.0, le=180.0)] = 0.0
    drift_period: _Positive = 1800.0
    gust: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)] = 0.0
    gust_time: _Positive = 5.0
    estimate_lag: _Positive = 10.0
    estimate_error: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)] = 0.0
    seed: Annotated[int, msgspec.Meta(ge=0, le=2**63 - 1)] = 0


class _AircraftTable(msgspec.Struct, forbid_unknown_fields=True):
    # None: the envelope's default (fleet.geo.aircraft.AircraftLimits).
    min_airspeed: _Limit | None = None
    max_airspeed: _Limit | None = None
    bank_limit_deg: _Limit | None = msgspec.field(default=None, name="bank_limit")
    roll_rate_deg: _Limit | None = msgspec.field(default=None, name="roll_rate")
    climb_rate: _Limit | None = None
    airspeed_rate: _Limit | None = None


class _UavTable(msgspec.Struct, forbid_unknown_fields=True):
    id: Annotated[int, msgspec.Meta(ge=MIN_PICCOLO_ID, le=MAX_PICCOLO_ID)]
    lat: _Lat
    lon: _Lon
    alt: _Alt
    heading: Annotated[float, msgspec.Meta(ge=0.0, lt=360.0)]
    airspeed: float
    plan: (
        Annotated[
            list[tuple[_Lat, _Lon, _Alt]], msgspec.Meta(min_length=1, max_length=MAX_INDEX + 1)
        ]
        | None
    ) = None


class _ScenarioFile(msgspec.Struct, forbid_unknown_fields=True):
    uav: Annotated[list[_UavTable], msgspec.Meta(min_length=1)]
    description: str = ""
    targets: Annotated[str, msgspec.Meta(min_length=1)] | None = None
    wind: _WindTable | None = None
    aircraft: _AircraftTable | None = None
    no_fly: Annotated[str, msgspec.Meta(min_length=1)] | None = None


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
    #: No-fly zones (the `no_fly` GeoJSON file beside the scenario): the simulator logs
    #: every incursion into them (fleet.sim.zone_log).
    zones: tuple[NoFlyZone, ...] = ()
    #: `wind` with its drift, gusts and the reported estimate's lag and error.
    weather: WeatherSpec = field(default_factory=WeatherSpec)

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


_AT = re.compile(r"^(?P<what>.*) - at `\$\.?(?P<where>[^`]*)`$")


def _schema_error(error: msgspec.ValidationError, source: str) -> ScenarioError:
    """msgspec's "Expected ... - at `$.uav[0].lat`" as "FILE: uav[0].lat: expected ..."."""
    text = str(error)
    match = _AT.match(text)
    if match is None:
        return ScenarioError(f"{source}: {text}")
    what = match["what"]
    where = match["where"] or "top level"
    return ScenarioError(f"{source}: {where}: {what[:1].lower()}{what[1:]}")


def _limits(table: _AircraftTable | None, source: str) -> AircraftLimits:
    if table is None:
        return AircraftLimits()
    try:
        given = {
            name: value
            for name, value in msgspec.structs.asdict(table).items()
            if value is not None
        }
        return AircraftLimits(**given)
    except ValueError as error:
        raise ScenarioError(f"{source}: aircraft: {error}") from error


def _weather(table: _WindTable | None, source: str, limits: AircraftLimits) -> WeatherSpec:
    if table is None:
        return WeatherSpec()
    weather = WeatherSpec(
        mean=Wind(north=table.north, east=table.east),
        drift_speed=table.drift_speed,
        drift_direction_deg=table.drift_direction,
        drift_period_s=table.drift_period,
        gust=table.gust,
        gust_time_s=table.gust_time,
        estimate_lag_s=table.estimate_lag,
        estimate_error=table.estimate_error,
        seed=table.seed,
    )
    # An aircraft slower than the wind cannot make way against it; no plan is flyable.
    # Gusts count at three standard deviations: rarer ones last a moment.
    if weather.strongest >= limits.min_airspeed:
        counted = "" if weather.steady else " (mean + drift_speed + 3 gust)"
        raise ScenarioError(
            f"{source}: wind: speed {weather.strongest:.1f} m/s{counted} must be below the "
            f"minimum airspeed {limits.min_airspeed:g} m/s"
        )
    return weather


def _uav(table: _UavTable, where: str, limits: AircraftLimits) -> UavSpec:
    # The airspeed's range is the scenario's own envelope, known only once it is read.
    if not limits.min_airspeed <= table.airspeed <= limits.max_airspeed:
        raise ScenarioError(
            f"{where}.airspeed: expected a number in [{limits.min_airspeed:g}, "
            f"{limits.max_airspeed:g}], got {table.airspeed!r}"
        )
    plan = tuple(table.plan) if table.plan is not None else None
    return UavSpec(table.id, table.lat, table.lon, table.alt, table.heading, table.airspeed, plan)


def _checked(data: _ScenarioFile, source: str, base_dir: Path | None, name: str) -> Scenario:
    limits = _limits(data.aircraft, source)
    weather = _weather(data.wind, source, limits)
    targets_path = None
    if data.targets is not None:
        targets_path = (base_dir or Path.cwd()) / data.targets
        if not targets_path.is_file():
            raise ScenarioError(f"{source}: targets: no such file {str(targets_path)!r}")
    uavs: list[UavSpec] = []
    for i, table in enumerate(data.uav):
        uav = _uav(table, f"{source}: uav[{i}]", limits)
        if any(other.piccolo_id == uav.piccolo_id for other in uavs):
            raise ScenarioError(f"{source}: uav[{i}].id: Piccolo ID {uav.piccolo_id} repeated")
        uavs.append(uav)
    return Scenario(
        name=name,
        source=source,
        uavs=tuple(uavs),
        wind=weather.mean,
        limits=limits,
        description=data.description,
        targets_path=targets_path,
        zones=_zones(data.no_fly, base_dir, source),
        weather=weather,
    )


def _zones(name: str | None, base_dir: Path | None, source: str) -> tuple[NoFlyZone, ...]:
    if name is None:
        return ()
    try:
        return read_zones((base_dir or Path.cwd()) / name)
    except ZonesFileError as error:
        raise ScenarioError(f"{source}: no_fly: {error}") from error
    except OSError as error:
        raise ScenarioError(f"{source}: no_fly: cannot read {name!r}: {error.strerror}") from error


def parse_scenario(
    text: bytes | str, source: str, base_dir: Path | None = None, name: str = ""
) -> Scenario:
    """Validate a scenario's TOML text. `source` names the file in errors; `base_dir`
    resolves the targets file (the current directory if None)."""
    try:
        data = msgspec.toml.decode(text, type=_ScenarioFile)
    except msgspec.ValidationError as error:
        raise _schema_error(error, source) from error
    except msgspec.DecodeError as error:
        raise ScenarioError(f"{source}: not valid TOML: {error}") from error
    return _checked(data, source, base_dir, name)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file; raises ScenarioError naming file and field."""
    path = Path(path)
    source = str(path)
    try:
        text = path.read_bytes()
    except OSError as error:
        raise ScenarioError(f"{source}: cannot read: {error.strerror or error}") from error
    return parse_scenario(text, source, path.parent, path.stem)


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
