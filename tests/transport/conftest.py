"""Fixtures of the transport tests that sign and route: one router and one set of
identities per module."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet.files.certs import write_identities
from fleet.transport.router import Router
from tests.support.processes import ANY_PORT


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The ground's, the router's and two UAVs' identities (no endpoint in them)."""
    where = tmp_path_factory.mktemp("certs")
    write_identities(where, ["router", "ground", "uav-74", "uav-112"], [])
    return where


@pytest.fixture(scope="module")
def endpoint() -> Iterator[str]:
    """A plain router of the test's own process, on a port it chose."""
    with Router([ANY_PORT]) as router:
        yield router.endpoints[0]
