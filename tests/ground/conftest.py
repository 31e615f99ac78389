"""Fixtures of the ground's tests: a router on loopback (or, where a module overrides
`router` with `memory_router`, an in-process bus) with two fake UAVs on it
(`FakeOnboard`), shared by the `ground-cli` and `ground-cli gui` tests of a module."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import pytest
import zenoh

from fleet.transport.router import Router
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import make_config
from tests.support.fake_onboard import FakeOnboard, fake_pair, memory_bus
from tests.support.processes import ANY_PORT


@pytest.fixture(scope="module")
def router() -> Iterator[str]:
    with Router([ANY_PORT]) as running:
        yield running.endpoints[0]


@pytest.fixture(scope="module")
def memory_router(request: pytest.FixtureRequest) -> Iterator[str]:
    """An in-process bus (`memory:NAME`, one per test module), as `--connect` takes it;
    a module runs its tests on it by overriding `router` with it."""
    with memory_bus(request.module.__name__) as spec:
        yield spec


@pytest.fixture(scope="module")
def fakes(router: str) -> Iterator[dict[int, FakeOnboard]]:
    """The two fake UAVs (74 and 112) on this module's `router`."""
    with fake_pair(router) as pair:
        yield pair


@contextmanager
def client_bus(router: str) -> Iterator[ZenohBus]:
    """A Zenoh client's bus on `router` (`.session` is its Zenoh session), closed on exit."""
    opened = ZenohBus(zenoh.open(make_config("client", [router])))
    try:
        yield opened
    finally:
        opened.close()


@pytest.fixture
def session(router: str) -> Iterator[ZenohBus]:
    """The ground's bus (`.session` is its Zenoh session)."""
    with client_bus(router) as opened:
        yield opened


@pytest.fixture
def rival(router: str) -> Iterator[ZenohBus]:
    """Another ground's bus."""
    with client_bus(router) as opened:
        yield opened
