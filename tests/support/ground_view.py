"""What the ground sees on the bus during a test, decoded by key: on a Zenoh session (the
end-to-end tests) or on any `Bus` (the in-memory fleet, `GroundView.on_bus`)."""

from __future__ import annotations

import math
import threading
import time

import msgspec
import zenoh

from fleet.geo.mercator import MercatorProjection
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.mission.messages import AssignmentReport, StatusText, TargetOutcome, UavResult
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.transport.bus import Bus, BusSample, Declaration

SPACE = KeySpace()


class GroundView:
    """Everything the ground sees under fleet/**, decoded by key."""

    def __init__(self, session: zenoh.Session | None = None) -> None:
        self.lock = threading.Lock()
        self.telemetry: dict[int, list[Telemetry]] = {}
        self.tracks: dict[int, list[int]] = {}
        self.assignments: dict[int, AssignmentReport] = {}
        #: When (monotonic s) each UAV's latest assignment arrived.
        self.assigned_at: dict[int, float] = {}
        #: Every report each UAV put on its re-plan key (the one its teammates hear).
        self.replans: dict[int, list[AssignmentReport]] = {}
        self.results: dict[int, UavResult] = {}
        #: Each UAV's standings for re-plans (fleet.consensus.resolve), in order heard.
        self.standings: dict[int, list[UavResult]] = {}
        #: Every TargetOutcome each UAV published, in order.
        self.outcomes: dict[int, list[TargetOutcome]] = {}
        self.status: dict[int, list[str]] = {}
        #: Every status message each UAV sent, whole (its kind, severity, mission).
        self.status_messages: dict[int, list[StatusText]] = {}
        self.subscriber: Declaration | None = None
        if session is not None:
            self.subscriber = session.declare_subscriber(SPACE.everything, self.on_sample)

    @classmethod
    def on_bus(cls, bus: Bus) -> GroundView:
        """What a ground on `bus` sees (the in-memory fleet's, say)."""
        view = cls()
        view.subscriber = bus.subscribe(SPACE.everything, view.on_bus_sample)
        return view

    def on_sample(self, sample: zenoh.Sample) -> None:
        self.take(str(sample.key_expr), sample.payload.to_bytes())

    def on_bus_sample(self, sample: BusSample) -> None:
        self.take(sample.key, sample.payload)

    def take(self, key: str, data: bytes) -> None:
        with self.lock:
            if key.endswith("/telemetry"):
                uav = uav_id_of(key)
                self.telemetry.setdefault(uav, []).append(msgspec.json.decode(data, type=Telemetry))
            elif key.endswith("/track"):
                track = msgspec.json.decode(data, type=Track)
                self.tracks.setdefault(uav_id_of(key), []).append(track.waypoint)
            elif "/assignment/" in key:
                report = msgspec.json.decode(data, type=AssignmentReport)
                self.assignments[report.uav] = report
                self.assigned_at[report.uav] = time.monotonic()
            elif "/replan/" in key:
                report = msgspec.json.decode(data, type=AssignmentReport)
                self.replans.setdefault(report.uav, []).append(report)
            elif "/outcome/" in key:
                outcome = msgspec.json.decode(data, type=TargetOutcome)
                self.outcomes.setdefault(outcome.uav, []).append(outcome)
            elif "/result/" in key:
                result = msgspec.json.decode(data, type=UavResult)
                if result.basis is not None:  # a standing for a re-plan, not the result
                    self.standings.setdefault(result.uav, []).append(result)
                else:
                    self.results[result.uav] = result
            elif key.endswith("/status"):
                status = msgspec.json.decode(data, type=StatusText)
                self.status.setdefault(uav_id_of(key), []).append(status.text)
                self.status_messages.setdefault(uav_id_of(key), []).append(status)

    def latest_track(self, uav: int) -> int | None:
        with self.lock:
            tracks = self.tracks.get(uav)
            return tracks[-1] if tracks else None

    def closest_approach(self, uav: int, lat: float, lon: float) -> float:
        projection = MercatorProjection(lat, lon)
        with self.lock:
            samples = list(self.telemetry.get(uav, []))
        distances = [
            math.hypot(*projection.to_xy(t.gps.lat, t.gps.lon))
            for t in samples
            if t.gps is not None
        ]
        return min(distances, default=math.inf)

    def outcomes_of(self, uav: int) -> list[TargetOutcome]:
        with self.lock:
            return list(self.outcomes.get(uav, []))

    def statuses(self, uav: int) -> list[str]:
        with self.lock:
            return list(self.status.get(uav, []))

    def close(self) -> None:
        if self.subscriber is not None:
            self.subscriber.undeclare()
