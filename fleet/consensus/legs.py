"""Target-to-target flight times: closed form, from the mission and each UAV's result.

A UAV's approach time to each target comes from its own model (its result); the time
from one target to the next (a leg) is timed here, in closed form, not by the approach
model, which is too slow for T x T legs (200 targets: 39,800 legs).

* `leg_times`: one table for every UAV, in still air at `LEG_SPEED_MPS`: the great-circle
  distance at that speed plus `LEG_TURN_S`. A target's neighbours are found by it.
* `AirLegs`: each UAV's own legs (docs/queues.md), in the air it flies: at the airspeed
  and in the smoothed wind its digested result carries (`Air.of`), so every UAV computes
  the same tables. A straight leg is flown at the ground speed along its track (the
  aircraft crabs into the crosswind, `fleet.geo.wind`), and the turn over the target
  just reached costs what a minimum-radius turn loses against flying straight:

      t(h, i, j) = (d + R cos(theta) - R) / g + K r (phi - sin(phi)) / g

  with d the leg's length, g its ground speed, R the acceptance radius (a target counts
  as reached R before it, and the turn starts there), theta the angle between the track
  into i and the track to j, phi the change of heading through the air (the two tracks'
  crab headings), r the turn radius at the airspeed (the bank limit). The track into a
  queue's first target is from where the UAV planned (its result's position). Against
  the simulated aircraft flying queues (0-15 m/s winds, 20-28 m/s): docs/benchmarks.md.
  The search plans with a table of pairs (`of`, the turn's mean over directions); a
  plan's arrivals, the ones it reports and is scored by, are timed with the turns its
  queues make (`arrivals`). A table's rows are computed when first asked (at 50 x 200
  the search asks a few hundred rows of each UAV, not 200).

With no-fly zones, a leg whose straight line crosses one is the shortest route around
them (fleet.geo.visibility.zone_map, the onboard's inflation, at `LEG_SPEED_MPS`): the
mission fixes the zones, so every UAV still computes the same routes; each UAV times a
route's straight pieces in its own air. A leg no route flies is infinite: the plan never
queues it.

Deterministic: the geometry is computed once per mission from the mission alone, and a
UAV's times from it and its result's numbers, by the same code on every UAV. Pure: no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from fleet.consensus.queues import LegTables, Matrix, Rows
from fleet.geo import great_circle
from fleet.geo.aircraft import AircraftLimits
from fleet.geo.mercator import MercatorProjection
from fleet.geo.visibility import Route, ZoneMap, legs_time, zone_map
from fleet.geo.wind import CALM_AIR, Wind, ground_speed_along
from fleet.mission.messages import NoFlyZone, Target, UavResult
from fleet.mission.no_fly import local_zones

#: The airspeed (m/s) a leg is flown at without a better one: the simulated cruise.
LEG_SPEED_MPS = 22.0
#: Seconds added to every leg for the turn over the target just reached: half a
#: standard-rate 360-degree turn (a 180-degree reversal at 3 deg/s takes 60 s; the mean
#: turn is about a quarter of that, rounded up).
LEG_TURN_S = 15.0


#: Metres from a target at which it counts as reached: the simulated autopilot's.
ACCEPTANCE_RADIUS_M = 60.0
#: The turn's weight K in the module docstring, fitted to the simulated aircraft.
TURN_WEIGHT = 1.1
#: The turn's mean over directions, in turn radii, in the table the search plans with.
MEAN_TURN_RADII = 0.5
#: The airspeeds (m/s) and winds a result may carry that are used; others are ignored
#: (the defaults are used instead), so that a wild number never enters a plan.
AIRSPEED_RANGE = (5.0, 100.0)
MAX_WIND_MPS = 60.0
#: A wind this share of the airspeed or more is flown in at that share (the approach
#: model's `PLANNABLE_WIND_SHARE`, a test checks they agree): no leg is flyable against
#: a wind as fast. A 15 m/s wind is 0.75 of a 20 m/s aircraft's airspeed.
WIND_SHARE = 0.8

_LIMITS = AircraftLimits()


def great_circle_m(a: Target, b: Target) -> float:
    """Metres along the great circle between two targets (fleet.geo.great_circle)."""
    return great_circle.great_circle_m(a.lat, a.lon, b.lat, b.lon)


def leg_times(
    targets: Sequence[Target],
    speed_mps: float = LEG_SPEED_MPS,
    turn_s: float = LEG_TURN_S,
    zones: Sequence[NoFlyZone] = (),
) -> list[list[float]]:
    """`legs[i][j]`: seconds from target i to target j (0 on the diagonal), around
    `zones` where the straight line crosses one."""
    count = len(targets)
    legs = [[0.0] * count for _ in range(count)]
    around = _zone_routes(targets, zones, speed_mps) if zones and count else None
    for i in range(count):
        for j in range(i + 1, count):
            metres = great_circle_m(targets[i], targets[j])
            if around is not None:
                metres = around(i, j, metres)
            legs[i][j] = legs[j][i] = metres / speed_mps + turn_s
    return legs


def _zone_routes(
    targets: Sequence[Target], zones: Sequence[NoFlyZone], speed_mps: float
) -> Callable[[int, int, float], float]:
    """A leg's metres around the zones: the great circle where the line is clear, else
    the shortest route's length (inf where none), on a plane centred on the first target."""
    projection = MercatorProjection(targets[0].lat, targets[0].lon)
    around = zone_map(local_zones(projection, zones), AircraftLimits(), speed_mps)
    points = [projection.to_xy(t.lat, t.lon) for t in targets]

    def metres(i: int, j: int, straight: float) -> float:
        if around.clear(points[i], points[j]):
            return straight
        route = around.route(points[i], points[j])
        return math.inf if route is None else route.length

    return metres


@dataclass(frozen=True, slots=True)
class Air:
    """How one UAV flies its legs: its airspeed (m/s), the wind it plans in, where it
    planned from (lat, lon; None if its result does not say)."""

    airspeed: float = LEG_SPEED_MPS
    wind: Wind = CALM_AIR
    origin: tuple[float, float] | None = None

    @classmethod
    def of(cls, result: UavResult) -> Air:
        """What `result` says, each number used only where it is plausible."""
        speed = result.airspeed
        if speed is None or not AIRSPEED_RANGE[0] <= speed <= AIRSPEED_RANGE[1]:
            speed = LEG_SPEED_MPS
        wind = CALM_AIR
        if result.wind_east is not None and result.wind_north is not None:
            given = Wind(result.wind_east, result.wind_north)
            if math.isfinite(given.speed) and given.speed <= MAX_WIND_MPS:
                wind = given.at_most(WIND_SHARE * speed)
        origin = None
        if result.lat is not None and result.lon is not None:
            origin = (result.lat, result.lon)
        return cls(speed, wind, origin)

    @property
    def turn_radius(self) -> float:
        """The radius (m) of its turns: at the bank limit, at its airspeed."""
        return _LIMITS.turn_radius(self.airspeed)


@dataclass(frozen=True, slots=True)
class LegGeometry:
    """What every leg's time is computed from, once per mission: each target's local
    position (metres on a plane centred on the first target), each leg's metres (the
    great circle, or the route around the zones; inf where none) and unit direction,
    and the routes that go round a zone."""

    projection: MercatorProjection | None
    points: tuple[tuple[float, float], ...]
    metres: tuple[tuple[float, ...], ...]
    east: tuple[tuple[float, ...], ...]
    north: tuple[tuple[float, ...], ...]
    routes: Mapping[tuple[int, int], Route]
    #: For each target, the targets a leg from it goes round a zone to, or reaches by
    #: no route (its metres infinite).
    routed_from: tuple[tuple[int, ...], ...] = ()

    @classmethod
    def of(cls, targets: Sequence[Target], zones: Sequence[NoFlyZone] = ()) -> LegGeometry:
        count = len(targets)
        if not count:
            return cls(None, (), (), (), (), {}, ())
        projection = MercatorProjection(targets[0].lat, targets[0].lon)
        points = tuple(projection.to_xy(t.lat, t.lon) for t in targets)
        metres = [[0.0] * count for _ in range(count)]
        east = [[0.0] * count for _ in range(count)]
        north = [[0.0] * count for _ in range(count)]
        routes: dict[tuple[int, int], Route] = {}
        zone_map = _zone_map(projection, zones) if zones else None
        for i in range(count):
            for j in range(i + 1, count):
                dx = points[j][0] - points[i][0]
                dy = points[j][1] - points[i][1]
                length = math.hypot(dx, dy)
                if length > 0.0:
                    east[i][j], north[i][j] = dx / length, dy / length
                    east[j][i], north[j][i] = -east[i][j], -north[i][j]
                distance = great_circle_m(targets[i], targets[j])
                if zone_map is not None and not zone_map.clear(points[i], points[j]):
                    there = zone_map.route(points[i], points[j])
                    back = zone_map.route(points[j], points[i])
                    distance = math.inf
                    if there is not None and back is not None:
                        routes[i, j], routes[j, i] = there, back
                        distance = there.length
                metres[i][j] = metres[j][i] = distance
        return cls(
            projection,
            points,
            tuple(map(tuple, metres)),
            tuple(map(tuple, east)),
            tuple(map(tuple, north)),
            routes,
            tuple(
                tuple(j for j in range(count) if (i, j) in routes or metres[i][j] == math.inf)
                for i in range(count)
            ),
        )

    @property
    def count(self) -> int:
        return len(self.points)


def _zone_map(projection: MercatorProjection, zones: Sequence[NoFlyZone]) -> ZoneMap:
    return zone_map(local_zones(projection, zones), _LIMITS, LEG_SPEED_MPS)


class _Rows(dict[int, list[float]]):
    """One UAV's pairwise legs, a row computed when first asked for: a dict whose
    `__missing__` computes it, so that reading a row already computed is a dict lookup
    in C (the search reads ~200,000 legs a decision at 50 x 200)."""

    def __init__(self, geometry: LegGeometry, air: Air) -> None:
        super().__init__()
        self.geometry = geometry
        self.air = Air(air.airspeed, air.wind.at_most(WIND_SHARE * air.airspeed), air.origin)

    def __missing__(self, i: int) -> list[float]:
        if not 0 <= i < self.geometry.count:
            raise IndexError(f"target {i} of {self.geometry.count}")
        row = self[i] = self._row(i)
        return row

    def _row(self, i: int) -> list[float]:
        geometry, air = self.geometry, self.air
        speed, wind_e, wind_n = air.airspeed, air.wind.east, air.wind.north
        square = speed * speed
        # Metres a leg is counted short by (half the acceptance radius: the mean of its
        # R cos(theta) - R) and metres its mean turn loses.
        offset = MEAN_TURN_RADII * air.turn_radius - 0.5 * ACCEPTANCE_RADIUS_M
        sqrt = math.sqrt
        metres_row = geometry.metres[i]
        if not wind_e and not wind_n:
            out = [(metres + offset) / speed for metres in metres_row]
        else:
            # The ground speed along a unit track (e, n): sqrt(V^2 - cross^2) + along,
            # and cross^2 = |w|^2 - along^2. The wind is at most WIND_SHARE of the
            # airspeed (`Air`), so the root's argument and the speed are positive. One
            # comprehension over the row (50 x 200: ~1,000 rows a decision).
            still = square - wind_e * wind_e - wind_n * wind_n
            out = [
                (metres + offset) / (sqrt(still + along * along) + along)
                for metres, along in zip(
                    metres_row,
                    [
                        wind_e * e + wind_n * n
                        for e, n in zip(geometry.east[i], geometry.north[i], strict=True)
                    ],
                    strict=True,
                )
            ]
        out[i] = 0.0
        for j in geometry.routed_from[i]:
            out[j] = self._routed(i, j, offset)
        if min(out) < 0.0:  # targets closer than the offset: a leg takes no time
            out = [max(time, 0.0) for time in out]
        return out

    def _routed(self, i: int, j: int, offset: float) -> float:
        route = self.geometry.routes.get((i, j))
        if route is None:
            return math.inf
        time = legs_time((route.start, *route.points), self.air.airspeed, self.air.wind)
        return time + max(offset, 0.0) / self.air.airspeed


class AirLegs(LegTables):
    """Each UAV's legs in its own air (the module docstring): `of(uav)` the pairwise
    table the search plans with, `arrivals` a queue timed with its turns."""

    def __init__(
        self,
        geometry: LegGeometry,
        air: Mapping[int, Air],
        reference: Matrix | None = None,
    ) -> None:
        self.geometry = geometry
        self.air = dict(air)
        self._reference = reference
        self._tables: dict[int, _Rows] = {}

    @property
    def count(self) -> int:
        return self.geometry.count

    def air_of(self, uav: int) -> Air:
        return self.air.get(uav, _DEFAULT_AIR)

    def of(self, uav: int) -> Rows:
        table = self._tables.get(uav)
        if table is None:
            table = self._tables[uav] = _Rows(self.geometry, self.air_of(uav))
        return table

    def reference(self) -> Matrix:
        if self._reference is None:
            self._reference = [
                [m / LEG_SPEED_MPS + LEG_TURN_S if j != i else 0.0 for j, m in enumerate(row)]
                for i, row in enumerate(self.geometry.metres)
            ]
        return self._reference

    def arrivals(self, uav: int, first: float, queue: Sequence[int]) -> list[float]:
        out = [first]
        clock = first
        befores: list[tuple[float, float] | int | None] = [self.origin_of(uav)]
        befores += queue
        for before, i, j in zip(befores, queue, queue[1:], strict=False):
            clock += self.turning_leg(uav, before, i, j)
            out.append(clock)
        return out

    def origin_of(self, uav: int) -> tuple[float, float] | None:
        """Where `uav` planned from (local metres of the geometry's plane), the point its
        track into its queue's first target starts; None where its result did not say."""
        air = self.air_of(uav)
        projection = self.geometry.projection
        if air.origin is None or projection is None:
            return None
        return projection.to_xy(*air.origin)

    def turning_leg(
        self, uav: int, before: tuple[float, float] | int | None, i: int, j: int
    ) -> float:
        """Seconds from target i to j for `uav` come to i from `before` (a target, a
        point, or None: unknown, the mean turn); a leg round a zone is the pairwise one."""
        air = self.air_of(uav)
        pairwise = self.of(uav)[i][j]
        geometry = self.geometry
        if before is None or (i, j) in geometry.routes or not math.isfinite(pairwise):
            return pairwise
        if isinstance(before, int):
            route = geometry.routes.get((before, i))
            # Come round a zone: the track in is the route's last piece.
            point = geometry.points[before] if route is None else (route.start, *route.points)[-2]
        else:
            point = before
        into = (geometry.points[i][0] - point[0], geometry.points[i][1] - point[1])
        length_in = math.hypot(*into)
        if length_in <= 0.0:
            return pairwise
        u_in = (into[0] / length_in, into[1] / length_in)
        u_out = (geometry.east[i][j], geometry.north[i][j])
        metres = geometry.metres[i][j]
        ground_in = ground_speed_along(u_in, air.airspeed, air.wind)
        ground_out = ground_speed_along(u_out, air.airspeed, air.wind) if metres > 0 else 0.0
        if ground_in <= 1e-6 or ground_out <= 1e-6:
            return pairwise
        wind = air.wind
        # The air velocities (each of magnitude the airspeed) that hold the two tracks.
        a_in = (u_in[0] * ground_in - wind.east, u_in[1] * ground_in - wind.north)
        a_out = (u_out[0] * ground_out - wind.east, u_out[1] * ground_out - wind.north)
        dot = a_in[0] * a_out[0] + a_in[1] * a_out[1]
        cross = a_in[0] * a_out[1] - a_in[1] * a_out[0]
        phi = math.atan2(abs(cross), dot)
        cos_theta = u_in[0] * u_out[0] + u_in[1] * u_out[1]
        straight = max(metres + ACCEPTANCE_RADIUS_M * (cos_theta - 1.0), 0.0)
        turn = TURN_WEIGHT * air.turn_radius * (phi - math.sin(phi))
        return (straight + turn) / ground_out


_DEFAULT_AIR = Air()


#: Metres behind the target just reached at which the track into it is taken to start
#: (along the velocity over the ground): only its direction matters.
_TRACK_IN_M = 100.0


def leg_from_here(
    geometry: LegGeometry, air: Air, velocity: tuple[float, float], i: int, j: int
) -> float | None:
    """Seconds from target i, just reached at `velocity` (east, north m/s over the
    ground), to target j in `air`: a plan's leg (`AirLegs.turning_leg`) timed in the air
    of the moment, the track into i the one flown. None where it has no finite time."""
    count = geometry.count
    if not (0 <= i < count and 0 <= j < count) or i == j:
        return None
    speed = math.hypot(*velocity)
    before: tuple[float, float] | None = None
    if math.isfinite(speed) and speed > 0.0:
        x, y = geometry.points[i]
        before = (x - _TRACK_IN_M * velocity[0] / speed, y - _TRACK_IN_M * velocity[1] / speed)
    held = Air(air.airspeed, air.wind.at_most(WIND_SHARE * air.airspeed))
    seconds = AirLegs(geometry, {0: held}).turning_leg(0, before, i, j)
    return seconds if math.isfinite(seconds) else None
