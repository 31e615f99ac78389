"""`ground-cli send-targets --no-fly` from its root: the real program in the test's
process on the in-process bus, two `FakeOnboard`s (tests/support/fake_onboard.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.files.targets_io import write_targets
from tests.ground.test_cli import TARGETS, assert_nothing_sent_since, run_cli
from tests.support.fake_onboard import FakeOnboard
from tests.support.waiting import wait_until


@pytest.fixture(scope="module")
def router(memory_router: str) -> str:
    """The fleet's bus: an in-process one (`memory:NAME`), as `--connect` takes it."""
    return memory_router


#: A square between the two targets TARGETS[0] and TARGETS[2] (none of them inside).
ZONE = [[-71.094, 42.356], [-71.086, 42.356], [-71.086, 42.359], [-71.094, 42.359]]


def zones_file(tmp_path: Path, ring: list[list[float]]) -> Path:
    path = tmp_path / "zones.geojson"
    feature = {
        "type": "Feature",
        "geometry": {"type": "Polygon", "coordinates": [[*ring, ring[0]]]},
        "properties": {"name": "restricted"},
    }
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    return path


def test_zones_travel_with_the_mission(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    done = run_cli(
        "send-targets", str(path), "--no-fly", str(zones_file(tmp_path, ZONE)), endpoint=router
    )
    assert done.returncode == 0, done.stderr
    assert "and 1 no-fly zones sent to" in done.stdout
    fake = fakes[74]
    assert wait_until(lambda: any(t.zones for t in fake.targets))
    zone = next(t for t in fake.targets if t.zones).zones[0]
    assert zone.name == "restricted"
    assert zone.ring[0] == (42.356, -71.094)


@pytest.mark.parametrize(
    ("ring", "where"),
    [
        # TARGETS[2] (42.3550, -71.0950) inside.
        ([[-71.1, 42.35], [-71.09, 42.35], [-71.09, 42.36], [-71.1, 42.36]], "target 2 is inside"),
        ([[-71.1, 42.35], [-71.09, 42.36], [-71.09, 42.35], [-71.1, 42.36]], "cross"),
    ],
)
def test_a_target_inside_a_zone_or_a_bad_zone_is_refused_and_nothing_sent(
    router: str,
    fakes: dict[int, FakeOnboard],
    tmp_path: Path,
    ring: list[list[float]],
    where: str,
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    zones = zones_file(tmp_path, ring)
    before = {uav: len(fake.targets) for uav, fake in fakes.items()}
    done = run_cli("send-targets", str(path), "--no-fly", str(zones), "--force", endpoint=router)
    assert done.returncode == 1
    assert str(zones) in done.stderr and where in done.stderr
    assert "nothing sent" in done.stderr
    assert_nothing_sent_since(router, fakes, before)
