"""`ground-cli send-targets` verifies the acknowledgement by content: a UAV that holds
another mission under the id sent (and ignores the new one, as an onboard does with an
id not above its own) is a collision, reported with a non-zero exit code, not
"delivered". On the in-process bus with fake UAVs (tests/support/fake_onboard.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet.consensus.targets_digest import targets_digest
from fleet.files.targets_io import write_targets
from fleet.mission.messages import Target
from tests.ground.test_cli import TARGETS, run_cli
from tests.support.fake_onboard import FakeOnboard
from tests.support.waiting import wait_until


@pytest.fixture(scope="module")
def router(memory_router: str) -> str:
    """The fleet's bus: an in-process one (`memory:NAME`), as `--connect` takes it."""
    return memory_router


OTHER = (Target(42.3620, -71.0920, 125.0),)


@pytest.mark.parametrize("follow", [(), ("--wait", "--timeout", "10")], ids=["", "wait"])
def test_a_uav_holding_another_mission_under_the_id_is_a_collision(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path, follow: tuple[str, ...]
) -> None:
    first, second = tmp_path / "first.bin", tmp_path / "second.bin"
    write_targets(first, TARGETS)
    write_targets(second, OTHER)
    sent = run_cli("send-targets", str(first), "--team", "74", "--json", endpoint=router)
    assert sent.returncode == 0, sent.stderr
    mission = json.loads(sent.stdout)["mission"]
    fake = fakes[74]
    assert wait_until(lambda: fake.mission is not None and fake.mission.mission == mission)
    assert fake.mission is not None
    held = fake.mission.targets_digest
    fake.keeps_current = True
    try:
        # Nothing serves the first mission's targets any more (its ground has exited, the
        # fake serves none), so the claim hears no rival: only the UAV's state tells.
        again = run_cli(
            "send-targets", str(second), "--team", "74", "--mission", str(mission), *follow,
            endpoint=router,
        )  # fmt: skip
    finally:
        fake.keeps_current = False
    assert again.returncode != 0, again.stdout
    assert f"UAV 74 holds another mission under id {mission}" in again.stderr
    assert "not delivered" in again.stderr
    # The second mission was put and the UAV kept the first: the report was right.
    assert wait_until(
        lambda: any(t.mission == mission and t.targets == OTHER for t in fake.targets)
    )
    first_held = next(t for t in fake.targets if t.mission == mission)
    assert first_held.targets == TARGETS
    assert fake.mission is not None and fake.mission.targets_digest == held
    assert held == targets_digest(first_held)
