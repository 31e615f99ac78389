"""Fixtures of the end-to-end tests: the processes a test starts, and the ground it
plays (a router on a free loopback port, a client session, and what it sees)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
import zenoh

from fleet.launch.launcher import free_port
from fleet.mission import keys
from fleet.mission.messages import MissionTargets
from fleet.transport.bus_codec import ENCODING, encode
from tests.support.ground_view import GroundView
from tests.support.processes import Fleet, client_session, router_session


@dataclass
class Ground:
    router: str  #: the endpoint onboard processes connect to
    session: zenoh.Session
    seen: GroundView

    def send(self, mission: MissionTargets) -> None:
        self.session.put(keys.mission_targets(mission.mission), encode(mission), encoding=ENCODING)


@pytest.fixture
def fleet() -> Iterator[Fleet]:
    processes = Fleet()
    try:
        yield processes
    finally:
        processes.stop_all()


@pytest.fixture
def ground() -> Iterator[Ground]:
    port = free_port()
    with router_session(port), client_session(port) as session:
        seen = GroundView(session)
        try:
            yield Ground(f"tcp/127.0.0.1:{port}", session, seen)
        finally:
            seen.close()
