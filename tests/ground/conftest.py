"""Fixtures of the ground's tests: a router on loopback with two fake UAVs on it
(`FakeOnboard`), shared by the `ground-cli` and `ground-cli gui` tests of a module."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import zenoh

from fleet.transport.router import Router
from fleet.transport.zenoh_bus import ZenohBus
from fleet.transport.zenoh_config import make_config
from tests.support.fake_onboard import FakeOnboard
from tests.support.processes import free_endpoint


@pytest.fixture(scope="module")
def router() -> Iterator[str]:
    endpoint = free_endpoint()
    with Router([endpoint]):
        yield endpoint


@pytest.fixture(scope="module")
def fakes(router: str) -> Iterator[dict[int, FakeOnboard]]:
    opened: dict[int, FakeOnboard] = {}
    try:
        opened[74] = FakeOnboard(router, 74, 42.3500, -71.1000, 150.0)
        opened[112] = FakeOnboard(router, 112, 42.3700, -71.0800, 160.0)
        yield opened
    finally:
        for fake in opened.values():
            fake.close()


@pytest.fixture
def session(router: str) -> Iterator[ZenohBus]:
    """The ground's bus (`.session` is its Zenoh session)."""
    opened = ZenohBus(zenoh.open(make_config("client", [router])))
    try:
        yield opened
    finally:
        opened.close()


@pytest.fixture
def rival(router: str) -> Iterator[ZenohBus]:
    """Another ground's bus."""
    opened = ZenohBus(zenoh.open(make_config("client", [router])))
    try:
        yield opened
    finally:
        opened.close()
