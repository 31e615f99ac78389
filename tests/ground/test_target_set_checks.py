"""`ground-cli send-targets` refuses target sets nobody should fly, naming the targets
and why, and sends nothing (so does a team naming a UAV that is not live); `--force`
sends them all the same. On the in-process bus with two fake UAVs near Boston (their
positions come from their state)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet.files.targets_io import write_targets
from fleet.mission.messages import Target
from tests.ground.test_cli import TARGETS, run_cli
from tests.support.fake_onboard import FakeOnboard


@pytest.fixture(scope="module")
def router(memory_router: str) -> str:
    """The fleet's bus: an in-process one (`memory:NAME`), as `--connect` takes it."""
    return memory_router


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        (Target(42.3602, -71.0901, 120.0), "targets 0 and 3: 14 m apart"),
        (Target(35.72, -120.76, 600.0), "target 3: 4290 km from the nearest team UAV (74)"),
        (
            Target(-42.36, 108.91, 100.0),
            "target 3: 20014 km from the nearest team UAV (74): on the far side",
        ),
    ],
    ids=["duplicate", "beyond-reach", "antipode"],
)
def test_a_target_set_nobody_should_fly_is_refused_and_nothing_sent(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path, extra: Target, said: str
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, (*TARGETS, extra))
    before = {uav: len(fake.targets) for uav, fake in fakes.items()}
    done = run_cli("send-targets", str(path), endpoint=router)
    assert done.returncode == 1
    assert f"error: {path}: {said}" in done.stderr, done.stderr
    assert "nothing sent (--force sends it all the same)" in done.stderr
    assert {uav: len(fake.targets) for uav, fake in fakes.items()} == before


def test_force_sends_it_all_the_same_with_warnings(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, (*TARGETS, Target(42.3602, -71.0901, 120.0)))
    done = run_cli("send-targets", str(path), "--force", endpoint=router)
    assert done.returncode == 0, done.stderr
    assert f"warning: {path}: targets 0 and 3: 14 m apart" in done.stderr
    assert "sent to 74, 112" in done.stdout


def test_a_team_naming_a_uav_that_is_not_live_is_refused_unless_forced(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    before = {uav: len(fake.targets) for uav, fake in fakes.items()}
    done = run_cli("send-targets", str(path), "--team", "74,999", endpoint=router)
    assert done.returncode == 1
    assert "error: not live now: 999 (no liveliness token); nothing sent" in done.stderr
    assert {uav: len(fake.targets) for uav, fake in fakes.items()} == before
    forced = run_cli("send-targets", str(path), "--team", "74,999", "--force", endpoint=router)
    assert forced.returncode == 0, forced.stderr
    assert "warning: not live now: 999" in forced.stderr
    assert "sent to 74, 999" in forced.stdout
