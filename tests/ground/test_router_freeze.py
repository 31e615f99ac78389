"""The router frozen mid-queue: every onboard loses every teammate for 15 s, releases
them all and flies on alone; when the router runs again each counts the others back in
(fleet.consensus.membership), the team converges on one plan, and every target is
reached (each by its UAV's own outcome: the ground's relayed telemetry has a 15 s gap
while the router is frozen, so it cannot be the witness). Real processes: a router of its own (so
that it can be frozen), simulator, onboards and the ground's Zenoh session."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, TargetOutcome
from fleet.mission.phase import Phase
from tests.conftest import Ground
from tests.onboard.test_multi_uav import ring_sim, start_onboard, wait_for_telemetry
from tests.support.ground_view import GroundView
from tests.support.processes import ANY_PORT, Child, Fleet, client_session, start_router
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

SPACE = KeySpace()
SPEEDUP = 5.0
#: Longer than Zenoh's lease (10 s) and the liveliness grace (2 s): every token goes.
FREEZE_S = 15.0
REACH_TIMEOUT_S = 150.0


@pytest.fixture
def frozen_ground() -> Iterator[tuple[Ground, Child]]:
    """A router process of its own, and the ground's session to it."""
    router, endpoint = start_router("--listen", ANY_PORT)
    try:
        with client_session(endpoint) as session:
            seen = GroundView(session)
            try:
                yield Ground(endpoint, session, seen), router
            finally:
                seen.close()
    finally:
        router.process.send_signal(signal.SIGCONT)
        router.stop()


def test_the_router_frozen_15_s_mid_queue_every_target_is_still_reached(
    fleet: Fleet, frozen_ground: tuple[Ground, Child], tmp_path: Path
) -> None:
    ground, router = frozen_ground
    endpoints = ring_sim(fleet, tmp_path, 3, SPEEDUP, 5.0)
    start_onboard(fleet, endpoints, ground.router)
    team = sorted(endpoints)
    wait_for_telemetry(ground, team)
    seen = ground.seen
    targets = ring_targets(6, seed=7)
    ground.send(MissionTargets(mission=1, team=tuple(team), targets=targets))
    wait_until(lambda: set(team) <= set(seen.assignments), 60.0, "every commitment")
    wait_until(
        lambda: any(o.phase == Phase.REACHED for u in team for o in seen.outcomes_of(u)),
        REACH_TIMEOUT_S,
        "a first target reached: mid-queue",
    )
    router.process.send_signal(signal.SIGSTOP)  # the fault: the router's process frozen
    frozen_at = time.monotonic()
    try:
        wait_until(lambda: time.monotonic() - frozen_at >= FREEZE_S, 30.0, "15 s frozen")
    finally:
        router.process.send_signal(signal.SIGCONT)

    def latest() -> dict[int, AssignmentReport]:
        """Each UAV's latest assignment, asked for (a put made while the ground's own
        session was reconnecting is not heard; every UAV answers with its latest)."""
        found: dict[int, AssignmentReport] = {}
        for reply in ground.session.get(SPACE.mission_assignments(1), timeout=5.0):
            if reply.ok is not None:
                report = msgspec.json.decode(reply.ok.payload.to_bytes(), type=AssignmentReport)
                found[report.uav] = report
        return found

    def converged() -> bool:
        reports = latest()
        one = len({(r.digest, r.epoch) for r in reports.values()}) == 1
        return (
            set(reports) == set(team)
            and one
            and reports[team[0]].epoch > 0
            and (not reports[team[0]].released)
        )

    # Each counted the others out while the router was frozen, and back once it ran.
    try:
        wait_until(converged, 60.0, "one plan again, with every UAV in it")
    except AssertionError:
        logs = "\n".join(line for c in fleet.children[1:] for line in c.history[-12:])
        mine = {u: (r.epoch, r.released) for u, r in latest().items()}
        raise AssertionError(f"{mine}\n{logs}") from None
    assert latest()[team[0]].back  # counted back in after counted out

    def reached() -> set[int]:
        """Targets some UAV said it reached, in its own outcomes: heard live, or asked
        for (an outcome put while the ground's session was reconnecting is not heard)."""
        found = {o.target for u in team for o in seen.outcomes_of(u) if o.phase == Phase.REACHED}
        for reply in ground.session.get(SPACE.mission_outcomes(1), timeout=5.0):
            if reply.ok is not None:
                outcome = msgspec.json.decode(reply.ok.payload.to_bytes(), type=TargetOutcome)
                found |= {t for t, by in outcome.reached.items() if by == outcome.uav}
        return {t for t in found if t is not None}

    def unreached() -> list[int]:
        return [index for index in range(len(targets)) if index not in reached()]

    try:
        wait_until(lambda: not unreached(), REACH_TIMEOUT_S, "every target reached")
    except AssertionError:
        counts = {u: len(seen.telemetry[u]) for u in team}
        logs = "\n".join(line for c in fleet.children[1:] for line in c.history[-12:])
        raise AssertionError(f"{unreached()} {counts}\n{logs}") from None
