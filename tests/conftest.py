"""Fixtures of the end-to-end tests: the processes a test starts, and the ground it
plays (a router on a loopback port the OS picks, a client session, and what it sees).

And the test tiers. A test that starts a process (a router, a simulator, an onboard,
ground-cli, chromium) is marked `e2e`: by hand (`pytestmark = pytest.mark.e2e` on a
module, `@pytest.mark.e2e` on a test) or here, for every test using a fixture that
starts processes. `pytest -m "not e2e"` is then the fast tier, and so that it stays
fast, a test not marked `e2e` that starts a process fails, saying to mark it.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, NoReturn

import pytest
import zenoh
from hypothesis import settings

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets
from fleet.transport.bus_codec import ENCODING, encode
from tests.support.ground_view import GroundView
from tests.support.processes import Fleet, client_session, router_session

# A run always ends, and fails on a crashed worker or a process left running.
pytest_plugins = ["tests.support.run_guard"]

# No test fails on an absolute time: Hypothesis's per-example deadline (200 ms) failed
# property tests on a loaded machine (load average 40) that pass in milliseconds alone.
settings.register_profile("fleet", deadline=None)
settings.load_profile("fleet")

SPACE = KeySpace()

E2E = "e2e"
#: Fixtures that start processes, or stand in for the ground of a test that does.
E2E_FIXTURES = frozenset({"fleet", "ground"})
#: An end-to-end test's time limit (pytest-timeout's; the others have pyproject's 300 s),
#: unless it sets its own: one waits on processes and flights, and on a loaded machine
#: its waits are stretched (tests/support/waiting.py); a hung one still ends.
E2E_TIME_LIMIT_S = 600.0


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", f"{E2E}: starts processes (routers, simulators, onboards, ground-cli, chromium)"
    )


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if E2E_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(E2E)
        if item.get_closest_marker(E2E) is not None and not item.get_closest_marker("timeout"):
            item.add_marker(pytest.mark.timeout(E2E_TIME_LIMIT_S))


class ProcessInFastTest(AssertionError):
    """A test not marked e2e started a process."""


@pytest.fixture(autouse=True)
def _no_process_unless_e2e(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> Iterator[None]:
    if request.node.get_closest_marker(E2E) is not None:
        yield
        return
    started: list[str] = []

    def refuse(what: str) -> NoReturn:
        started.append(what)
        raise ProcessInFastTest(f"{what} in a test not marked e2e: mark it @pytest.mark.e2e")

    def popen(self: subprocess.Popen[Any], args: object, *rest: object, **kw: object) -> None:
        refuse(f"subprocess {args!r}")

    monkeypatch.setattr(subprocess.Popen, "__init__", popen)
    monkeypatch.setattr(os, "fork", lambda: refuse("os.fork()"))
    monkeypatch.setattr(os, "system", lambda command: refuse(f"os.system({command!r})"))
    monkeypatch.setattr(os, "posix_spawn", lambda path, *_: refuse(f"posix_spawn({path!r})"))
    yield
    if started:  # even if the test caught the error
        pytest.fail(f"{started[0]} in a test not marked e2e: mark it @pytest.mark.e2e")


@dataclass
class Ground:
    router: str  #: the endpoint onboard processes connect to
    session: zenoh.Session
    seen: GroundView

    def send(self, mission: MissionTargets) -> None:
        self.session.put(SPACE.mission_targets(mission.mission), encode(mission), encoding=ENCODING)


@pytest.fixture
def fleet() -> Iterator[Fleet]:
    processes = Fleet()
    try:
        yield processes
    finally:
        processes.stop_all()


@pytest.fixture
def ground() -> Iterator[Ground]:
    with router_session() as router, client_session(router.endpoints[0]) as session:
        seen = GroundView(session)
        try:
            yield Ground(router.endpoints[0], session, seen)
        finally:
            seen.close()
