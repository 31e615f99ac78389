"""`ground-cli` against a hostile bus: a rogue client on the open router answers
`fleet/uav/999/state` and publishes under UAV 999's and the mission's keys with deeply
nested JSON, huge payloads, the wrong schema, or messages its keys do not vouch for.
Every command still ends with its own status and no traceback, refuses and counts the
rogue's messages, and still sees the real (fake) UAVs correctly.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from fleet.files.targets_io import write_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionProgress, UavResult, UavState
from fleet.mission.phase import Phase
from fleet.transport.bus import Queryable
from fleet.transport.bus_codec import MAX_PAYLOAD_BYTES, encode
from fleet.transport.bus_factory import open_bus
from tests.ground.test_cli import TARGETS, run_cli
from tests.support.fake_onboard import FakeOnboard

SPACE = KeySpace()


@pytest.fixture(scope="module")
def router(memory_router: str) -> str:
    """The fleet's bus, the rogue's too: an in-process one (`memory:NAME`)."""
    return memory_router


DEPTH = 50_000  #: 300 kB: under the size limit, far over any nesting limit
PAYLOADS = {
    "nested": b'{"a":' * DEPTH + b"1" + b"}" * DEPTH,
    "nested-array": b"[" * DEPTH + b"]" * DEPTH,
    "huge": b'"' + b"x" * (2 * MAX_PAYLOAD_BYTES) + b'"',
    "wrong-schema": b'{"uav": 999, "enabled": "yes"}',
    # Valid messages that their keys do not vouch for.
    "wrong-key": encode(
        UavState(74, True, 1.0, None, None, None, MissionProgress(2**33, Phase.IDLE, 1))
    ),
}


class Rogue:
    """A client that answers and publishes `payload` wherever the ground looks."""

    def __init__(self, where: str, payload: bytes) -> None:
        self.payload = payload
        self.bus = open_bus(where)
        self.stop = threading.Event()
        self.queryables: list[Queryable] = []
        self.queryables = [
            self.bus.declare_queryable(SPACE.state(999), self._answer),
            self.bus.declare_queryable("fleet/mission/**", self._answer),
        ]
        self.declared: list[Any] = [
            *self.queryables,
            self.bus.declare_token(SPACE.alive(999)),
            self.bus.declare_token("fleet/uav/abc/alive"),
        ]
        self.thread = threading.Thread(target=self._publish, daemon=True)
        self.thread.start()

    def _answer(self) -> None:
        answers = (
            SPACE.state(999),
            "fleet/uav/abc/state",
            SPACE.mission_result(7, 74),
            SPACE.mission_targets(2**32 - 1),  # would make the next mission id 2^32
        )
        for queryable in self.queryables:
            while (query := queryable.try_recv()) is not None:
                for key in answers:
                    if query.intersects(key):
                        query.reply_bytes(key, self.payload)
                query.drop()

    def _publish(self) -> None:
        forged = encode(UavResult(7, 112, (1.0, 1.0, 1.0)))
        while not self.stop.wait(0.2):
            for leaf in ("telemetry", "track", "waypoint/3", "status"):
                self.bus.put(SPACE.uav(999, leaf), self.payload)
            self.bus.put(SPACE.mission_result(7, 74), forged)
            self.bus.put(SPACE.mission_assignment(7, 999), self.payload)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        for declared in self.declared:
            declared.undeclare()
        self.bus.close()


@pytest.fixture(params=sorted(PAYLOADS))
def rogue(request: pytest.FixtureRequest, router: str) -> Iterator[Rogue]:
    attacker = Rogue(router, PAYLOADS[request.param])
    try:
        yield attacker
    finally:
        attacker.close()


def survived(done: object, *ok: int) -> str:
    assert hasattr(done, "returncode") and hasattr(done, "stderr")
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert done.returncode in ok, done.stderr[-3000:]
    return str(done.stderr)


def test_every_ground_command_survives_and_counts_the_rogue(
    router: str, fakes: dict[int, FakeOnboard], rogue: Rogue, tmp_path: Path
) -> None:
    listed = run_cli("uavs", "--json", endpoint=router)
    survived(listed, 0)
    rows = {row["id"]: row for row in json.loads(listed.stdout)}
    assert rows[74]["lat"] == pytest.approx(fakes[74].lat)  # the real ones, correct
    assert rows[112]["alt"] == pytest.approx(fakes[112].alt)
    assert "refused" in listed.stderr
    # UAV 999 is live (its token is real) but nothing it said about itself was believed.
    assert rows[999]["lat"] is None and rows[999]["enabled"] is None

    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    sent = run_cli("send-targets", str(path), "--team", "74,112", "--wait", "--json",
                   "--timeout", "15", endpoint=router)  # fmt: skip
    survived(sent, 0)
    outcome = json.loads(sent.stdout)
    assert outcome["agreed"] is True and outcome["mission"] < 2**32 - 1

    survived(run_cli("abort", endpoint=router), 0)
    watched = run_cli("watch", "--count", "2", "--interval", "0.3", endpoint=router)
    survived(watched, 0)
    assert "refused" in watched.stderr
    shown = run_cli("keys", "fleet/uav/999/**", "--json", "--window", "0.5", endpoint=router)
    survived(shown, 0)
    json.loads(shown.stdout)
