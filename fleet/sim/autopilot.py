"""One simulated Piccolo autopilot: aircraft, guidance, flight plan and its two ports.

Bytes in, bytes out, stepped by simulated time; no sockets and no clock (the server in
`fleet.sim.server` owns those). Everything here happens at the simulated instant
`time_ms`, which only `step` advances, so a run is reproducible: the same scenario and
the same bytes fed at the same simulated instants give the same flight.

Program port (autopilot stream, id 3), every connection with its own `PiccoloLink`
(decoder state and sequence numbers are per serial line):

* TELEMETRY_HI_RES (GPS, sensor and raw blocks) every 1 / telemetry_hz simulated
  seconds, from the Piccolo ID to all operator interfaces (0xFFFE);
* TRACK (the waypoint being tracked) when it changes, and once a simulated second
  besides, so that a module connecting late learns it without asking;
* a WAYPOINT addressed to this autopilot (or broadcast 0xFFFF) is stored and echoed; a
  TRACK is obeyed and echoed. A TRACK naming a waypoint that is not stored is refused
  and answered with the waypoint still tracked, so the sender sees the refusal;
* every byte that is not a valid packet is dropped by the link decoder and counted; the
  aircraft never sees it. Valid packets the autopilot does not act on are counted too.

What the autopilot sends is mirrored to every open program connection, as the Piccolo's
program port mirrors the whole ground link.

Payload port (stream 6): a transparent pipe, as on a Piccolo. Bytes from the onboard
side come out of the ground side and back, verbatim, through bounded buffers that drop
their oldest bytes when nobody reads.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from dataclasses import dataclass, field

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.angles import wrap_pi
from fleet.geo.mercator import MercatorProjection
from fleet.mission.messages import NoFlyZone
from fleet.payload.link import AutopilotEvent, PiccoloLink
from fleet.piccolo.autopilot_messages import AutopilotMessage, UnknownAutopilotMessage
from fleet.piccolo.stream_packet import ALL_OPERATOR_INTERFACES, BROADCAST_AVIONICS
from fleet.piccolo.stream_queue import StreamQueue
from fleet.piccolo.telemetry import GpsBlock, RawBlock, SensorBlock, Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from fleet.sim.aircraft import CALM, AircraftState, Wind
from fleet.sim.flight_model import Dynamics, FlightModel, FlightModelError, make_flight_model
from fleet.sim.flight_plan import FlightPlan, FlightPlanError, check_indices
from fleet.sim.guidance import DEFAULT_ACCEPTANCE_RADIUS, GuidanceSettings, command_toward
from fleet.sim.uav_spec import UavSpec
from fleet.sim.weather import Weather, WeatherSpec
from fleet.sim.zone_log import IncursionLog

logger = logging.getLogger(__name__)

#: Fixed integration step (simulated milliseconds).
STEP_MS = 20
#: Telemetry cannot be faster than one packet a step.
MAX_TELEMETRY_HZ = 1000.0 / STEP_MS
DEFAULT_TELEMETRY_HZ = 20.0
#: Period of the unsolicited TRACK report (simulated milliseconds).
TRACK_REPORT_PERIOD_MS = 1000
#: Bytes each outgoing buffer holds before dropping its oldest (about 5 s of 20 Hz
#: telemetry, far more than any reader that is merely slow).
OUTPUT_CAPACITY = 64 * 1024
#: Simulated time 0 is the start of this GPS week; GPS time is simulated time from it.
GPS_EPOCH_WEEK = 2300
_MS_PER_WEEK = 7 * 24 * 3600 * 1000
# Mercator (and any autopilot) cannot use a waypoint beyond these.
_MAX_WAYPOINT_LAT = 85.0


def bounded_buffer() -> StreamQueue:
    """An output FIFO that drops its oldest bytes when nobody reads (the link's own queue)."""
    return StreamQueue(capacity=OUTPUT_CAPACITY)


@dataclass
class ProgramConnection:
    """One client of the program port: its link state and what waits to be sent to it."""

    name: str
    link: PiccoloLink
    output: StreamQueue = field(default_factory=bounded_buffer)


@dataclass
class PayloadPipe:
    """The payload port's transparent pipe between the onboard and the ground side."""

    to_ground: StreamQueue = field(default_factory=bounded_buffer)
    to_onboard: StreamQueue = field(default_factory=bounded_buffer)

    def from_onboard(self, data: bytes) -> None:
        self.to_ground.append(data)

    def from_ground(self, data: bytes) -> None:
        self.to_onboard.append(data)


@dataclass(frozen=True, slots=True)
class AutopilotSettings:
    telemetry_hz: float = DEFAULT_TELEMETRY_HZ
    acceptance_radius: float = DEFAULT_ACCEPTANCE_RADIUS
    limits: AircraftLimits = field(default_factory=AircraftLimits)
    wind: Wind = CALM  #: steady, reported exactly, unless the autopilot is given weather
    #: No-fly zones whose incursions the simulator logs (fleet.sim.zone_log).
    zones: tuple[NoFlyZone, ...] = ()
    #: The flight model the aircraft fly (fleet.sim.flight_model).
    dynamics: Dynamics = Dynamics.KINEMATIC

    def __post_init__(self) -> None:
        if not 0.0 < self.telemetry_hz <= MAX_TELEMETRY_HZ:
            raise ValueError(
                f"telemetry rate must be in (0, {MAX_TELEMETRY_HZ:g}] Hz, got {self.telemetry_hz}"
            )
        if not (math.isfinite(self.acceptance_radius) and self.acceptance_radius > 0.0):
            raise ValueError(f"acceptance radius must be positive, got {self.acceptance_radius}")


def isa_atmosphere(alt: float) -> tuple[float, float, float]:
    """(density ratio, temperature in deg C, static pressure in Pa) of the ISA
    troposphere at `alt` metres."""
    theta = max(1.0 - 2.25577e-5 * alt, 0.1)
    return theta**4.25588, 15.0 - 0.0065 * alt, 101_325.0 * theta**5.25588


class SimulatedAutopilot:
    """A Piccolo autopilot flying one aircraft of a scenario."""

    def __init__(
        self,
        uav: UavSpec,
        settings: AutopilotSettings | None = None,
        weather: WeatherSpec | None = None,
    ) -> None:
        """`weather` (drift, gusts, the reported estimate's lag and error:
        fleet.sim.weather) replaces the settings' steady wind. Raises
        FlightModelError if the settings' dynamics cannot run here or cannot start this
        aircraft, ValueError if it cannot fly at the aircraft's airspeed."""
        self.settings = AutopilotSettings() if settings is None else settings
        self.piccolo_id = uav.piccolo_id
        self.projection = MercatorProjection(uav.lat, uav.lon)
        self.airspeed_command = uav.airspeed
        spec = weather or WeatherSpec(mean=self.settings.wind)
        self.weather = Weather(spec, uav.piccolo_id)
        start = AircraftState(
            x=0.0,
            y=0.0,
            alt=uav.alt,
            heading=math.radians(uav.heading),
            airspeed=uav.airspeed,
        )
        #: What the aircraft is: the kinematic model or JSBSim (settings.dynamics).
        try:
            self.model: FlightModel = make_flight_model(
                self.settings.dynamics,
                start,
                self.settings.limits,
                self.projection,
                self.weather.wind,
            )
        except (FlightModelError, ValueError) as error:
            raise type(error)(f"uav {uav.piccolo_id}: {error}") from error
        self.guidance = GuidanceSettings(acceptance_radius=self.settings.acceptance_radius)
        self.zone_log = IncursionLog(self.piccolo_id, self.projection, self.settings.zones)
        self.plan = FlightPlan(uav.waypoints())
        first = self.plan.waypoints()[0]
        self.tracked = first.index
        self._target = self._local(first)
        self.time_ms = 0
        self.payload = PayloadPipe()
        #: What the autopilot did with valid packets, by kind (see docs/simulator.md).
        self.counters: Counter[str] = Counter()
        self._connections: list[ProgramConnection] = []
        self._closed_drops: Counter[str] = Counter()
        self._telemetry_period_ms = 1000.0 / self.settings.telemetry_hz
        self._next_telemetry_ms = self._telemetry_period_ms
        self._next_track_report_ms = 0
        self._dead_end: int | None = None

    # -- the aircraft -------------------------------------------------------------

    def _local(self, waypoint: Waypoint) -> tuple[float, float, float]:
        x, y = self.projection.to_xy(waypoint.lat, waypoint.lon)
        return x, y, waypoint.alt

    @property
    def state(self) -> AircraftState:
        """Where the aircraft is and how it flies (its flight model's)."""
        return self.model.state

    @property
    def target_xy(self) -> tuple[float, float]:
        """Local metres of the tracked waypoint."""
        return self._target[0], self._target[1]

    def position(self) -> tuple[float, float, float]:
        """(lat, lon, alt) of the aircraft."""
        lat, lon = self.projection.to_latlon(self.state.x, self.state.y)
        return lat, lon, self.state.alt

    def step(self) -> None:
        """Advance the simulation by one step (20 ms simulated)."""
        x, y, alt = self._target
        wind = self.weather.wind
        command = command_toward(
            self.state,
            (x, y),
            alt,
            self.airspeed_command,
            self.settings.limits,
            wind,
            self.guidance,
        )
        self.model.step(command, wind, STEP_MS / 1000.0)
        self.weather.advance(STEP_MS / 1000.0)
        self.time_ms += STEP_MS
        self.zone_log.check(self.state.x, self.state.y, self.time_ms)
        if math.hypot(x - self.state.x, y - self.state.y) <= self.guidance.acceptance_radius:
            self._arrive()
        if self.time_ms >= self._next_telemetry_ms:
            self._send(self.telemetry(), ALL_OPERATOR_INTERFACES)
            # From the schedule, not from now: the rate does not drift with the step.
            while self._next_telemetry_ms <= self.time_ms:
                self._next_telemetry_ms += self._telemetry_period_ms
        if self.time_ms >= self._next_track_report_ms:
            self._send(Track(self.tracked), ALL_OPERATOR_INTERFACES)
            self._next_track_report_ms += TRACK_REPORT_PERIOD_MS

    def advance_to(self, time_ms: int) -> None:
        """Step until simulated time reaches `time_ms` (to the step at or before it)."""
        while self.time_ms + STEP_MS <= time_ms:
            self.step()

    def _arrive(self) -> None:
        reached = self.plan.get(self.tracked)
        if reached is None or reached.next_index not in self.plan:
            # Nothing to go on to: keep tracking it (the aircraft circles back over it).
            # Said once, not at every step spent within the acceptance radius.
            if self._dead_end != self.tracked:
                self._dead_end = self.tracked
                self.counters["arrivals_without_next"] += 1
                logger.warning(
                    "uav %d: reached waypoint %d whose next is not stored; still tracking it",
                    self.piccolo_id,
                    self.tracked,
                )
            return
        self.counters["arrivals"] += 1
        # The simulator's own record of an arrival, whatever the link let the module see.
        logger.info(
            "uav %d: reached waypoint %d, on to %d",
            self.piccolo_id,
            self.tracked,
            reached.next_index,
        )
        self._track(reached.next_index)
        self._send(Track(self.tracked), ALL_OPERATOR_INTERFACES)

    def _track(self, index: int) -> None:
        waypoint = self.plan.get(index)
        if waypoint is None:
            raise FlightPlanError(f"waypoint {index} is not stored")
        self.tracked = index
        self._target = self._local(waypoint)
        self._dead_end = None

    def telemetry(self) -> Telemetry:
        """TELEMETRY_HI_RES of the current state at the current simulated time."""
        state = self.state
        sensors = self.model.sensors(self.weather.wind)
        lat, lon = self.projection.to_latlon(state.x, state.y)
        reported = self.weather.estimate
        density, temperature, pressure = isa_atmosphere(state.alt)
        week, time_of_week = divmod(self.time_ms, _MS_PER_WEEK)
        return Telemetry(
            system_time_ms=self.time_ms & 0xFFFFFFFF,
            gps=GpsBlock(
                lat=lat,
                lon=lon,
                alt=state.alt,
                vel_north=sensors.vel_north,
                vel_east=sensors.vel_east,
                vel_down=sensors.vel_down,
                dop=1.0,
                sats_visible=12,
                sats_tracked=10,
                gps_week=GPS_EPOCH_WEEK + week,
                gps_time_of_week_ms=time_of_week,
            ),
            sensor=SensorBlock(
                roll=math.degrees(sensors.roll),
                pitch=math.degrees(sensors.pitch),
                # The wire holds +-pi in an i16 of 1e-4 rad: 0-360 would not fit.
                yaw=math.degrees(wrap_pi(sensors.yaw)),
                indicated_airspeed=state.airspeed * math.sqrt(density),
                wind_south=-reported.north,
                wind_west=-reported.east,
                density_ratio=density,
                outside_air_temp=round(temperature),
                static_pressure=pressure,
            ),
            raw=RawBlock(
                p=math.degrees(sensors.p),
                q=math.degrees(sensors.q),
                r=math.degrees(sensors.r),
                accel_x=sensors.accel_x,
                accel_y=sensors.accel_y,
                accel_z=sensors.accel_z,
            ),
        )

    # -- the program port ---------------------------------------------------------

    def open_program(self, name: str = "program") -> ProgramConnection:
        """A new program-port client (a TCP connection, or the pty for its lifetime)."""
        connection = ProgramConnection(name=name, link=PiccoloLink(local_address=self.piccolo_id))
        self._connections.append(connection)
        return connection

    def close_program(self, connection: ProgramConnection) -> None:
        if connection in self._connections:
            self._connections.remove(connection)
            self._closed_drops.update(connection.link.drop_counters())
            self._closed_drops["output_overflow_bytes"] += connection.output.overflow_bytes

    @property
    def connections(self) -> tuple[ProgramConnection, ...]:
        return tuple(self._connections)

    def link_drops(self) -> dict[str, int]:
        """Bytes and packets dropped on the program port so far, all connections."""
        totals = Counter(self._closed_drops)
        for connection in self._connections:
            totals.update(connection.link.drop_counters())
            totals["output_overflow_bytes"] += connection.output.overflow_bytes
        return dict(totals)

    def receive(self, connection: ProgramConnection, data: bytes) -> None:
        """Bytes read from a program-port client, acted on at the current simulated time."""
        for event in connection.link.feed(data, self.time_ms / 1000.0):
            if not isinstance(event, AutopilotEvent):
                # The payload stream belongs on the payload port.
                self.counters["ignored_payload_packets"] += 1
                continue
            if event.header.destination not in (self.piccolo_id, BROADCAST_AVIONICS):
                self.counters["not_addressed_to_us"] += 1
                continue
            self._command(event.message, event.header.source)

    def _command(self, message: AutopilotMessage, source: int) -> None:
        if isinstance(message, Waypoint):
            self._store_waypoint(message, source)
        elif isinstance(message, Track):
            self._command_track(message, source)
        elif isinstance(message, UnknownAutopilotMessage):
            self.counters["ignored_unknown_packets"] += 1
        else:
            self.counters["ignored_telemetry"] += 1

    def _store_waypoint(self, waypoint: Waypoint, source: int) -> None:
        try:
            check_indices(waypoint)
        except FlightPlanError as error:
            self._refuse("refused_waypoints", f"waypoint refused: {error}")
            return
        if abs(waypoint.lat) > _MAX_WAYPOINT_LAT or abs(waypoint.lon) > 180.0:
            self._refuse(
                "refused_waypoints",
                f"waypoint {waypoint.index} refused: ({waypoint.lat}, {waypoint.lon}) "
                "is not a usable position",
            )
            return
        self.plan.store(waypoint)
        self._dead_end = None
        self.counters["waypoints_stored"] += 1
        if waypoint.index == self.tracked:
            self._target = self._local(waypoint)
        logger.info(
            "uav %d: stored waypoint %d (%.6f, %.6f, %.0f m) next %d",
            self.piccolo_id,
            waypoint.index,
            waypoint.lat,
            waypoint.lon,
            waypoint.alt,
            waypoint.next_index,
        )
        self._send(waypoint, source)

    def _command_track(self, track: Track, source: int) -> None:
        if track.waypoint not in self.plan:
            self._refuse(
                "refused_tracks",
                f"track to waypoint {track.waypoint} refused: not stored; "
                f"still tracking {self.tracked}",
            )
            self._send(Track(self.tracked), source)
            return
        self._track(track.waypoint)
        self.counters["tracks_commanded"] += 1
        logger.info("uav %d: tracking waypoint %d", self.piccolo_id, self.tracked)
        self._send(track, source)

    def _refuse(self, counter: str, reason: str) -> None:
        self.counters[counter] += 1
        logger.warning("uav %d: %s", self.piccolo_id, reason)

    def _send(self, message: AutopilotMessage, destination: int) -> None:
        for connection in self._connections:
            connection.output.append(connection.link.encode_autopilot(message, destination))
