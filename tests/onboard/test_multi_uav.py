"""Thesis 4.4 and beyond, end to end: several onboard processes, real Zenoh, simulated
autopilots over real serial links (socket://), the test as the ground station.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterable
from pathlib import Path

from fleet.launch.endpoints import SimEndpoints
from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets
from tests.conftest import Ground
from tests.support.processes import Fleet
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()

#: The killed-UAV mission's deadline: long, so that committing early is clearly the
#: liveliness exclusion and not the deadline.
KILLED_DEADLINE_S = 30.0
#: Zenoh's lease (10 s by default): a UAV frozen (SIGSTOP) while the mission is sent stays
#: frozen until the router has dropped its liveliness token, which takes about this long.
FROZEN_S = 10.0


def token_present(ground: Ground, key: str) -> bool:
    """Whether the router holds the liveliness token `key` now."""
    return any(reply.ok is not None for reply in ground.session.liveliness().get(key, timeout=2.0))


def assert_agreed(reports: dict[int, AssignmentReport], team: set[int], n_targets: int) -> None:
    assert set(reports) == team
    first = next(iter(reports.values()))
    for report in reports.values():
        assert (report.pairs, report.digest, report.unassigned) == (
            first.pairs,
            first.digest,
            first.unassigned,
        ), f"UAV {report.uav} disagrees"
        assert report.target == first.pairs.get(report.uav)
    assert {uav: r.queues for uav, r in reports.items()} == {uav: first.queues for uav in reports}
    targets = list(first.pairs.values())
    assert len(targets) == len(set(targets)) == min(len(team), n_targets)
    # Every target in exactly one queue, or unserved.
    queued = [t for queue in first.queues.values() for t in queue]
    assert sorted([*queued, *first.unassigned]) == list(range(n_targets))


def ring_sim(
    fleet: Fleet, tmp_path: Path, count: int, speedup: float = 10.0, telemetry_hz: float = 2.0
) -> dict[int, SimEndpoints]:
    """Simulated autopilots for `count` UAVs on a ring; no onboard modules yet."""
    scenario = tmp_path / "ring.toml"
    scenario.write_text(ring_scenario(count))
    return fleet.sim(str(scenario), speedup, telemetry_hz)


def start_onboard(fleet: Fleet, endpoints: dict[int, SimEndpoints], router: str) -> None:
    """An onboard module for each simulated autopilot of `endpoints`."""
    for uav, where in endpoints.items():
        fleet.onboard(uav, where, router)


def wait_for_telemetry(ground: Ground, uavs: Iterable[int]) -> None:
    team = set(uavs)
    wait_until(lambda: team <= set(ground.seen.telemetry), 60.0, f"telemetry from {sorted(team)}")


def start_ring(
    fleet: Fleet,
    ground: Ground,
    tmp_path: Path,
    count: int,
    speedup: float = 10.0,
    telemetry_hz: float = 2.0,
) -> list[int]:
    """`count` UAVs on a ring, each with its onboard module; their IDs in order, once the
    ground sees telemetry from every one."""
    endpoints = ring_sim(fleet, tmp_path, count, speedup, telemetry_hz)
    start_onboard(fleet, endpoints, ground.router)
    team = sorted(endpoints)
    wait_for_telemetry(ground, team)
    return team


# Two UAVs head on reaching distinct targets and resuming, five UAVs then four, a result
# lost on the bus recovered by query, a new mission in flight: in memory,
# tests/onboard/test_multi_uav_in_memory.py.


def test_uav_killed_during_the_exchange_is_left_out(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    seen = ground.seen
    team = start_ring(fleet, ground, tmp_path, 3)
    victim = fleet.children[-1]  # the onboard process of the last UAV
    assert victim.name == f"onboard {team[-1]}"
    mission = MissionTargets(
        mission=1, team=tuple(team), targets=ring_targets(3, seed=7), deadline_s=KILLED_DEADLINE_S
    )
    sent_at = time.monotonic()
    ground.send(mission)
    victim.kill()  # SIGKILL, while the others compute
    survivors = set(team[:-1])
    wait_until(
        lambda: survivors <= set(seen.assignments),
        2 * KILLED_DEADLINE_S,
        "the survivors' assignments",
    )
    # Its result never came, so only the liveliness exclusion can let the survivors commit
    # before the deadline; without it they would wait the whole deadline out.
    assert team[-1] not in seen.results, "the victim published before dying: nothing tested"
    took = max(seen.assigned_at[u] for u in survivors) - sent_at
    assert took < KILLED_DEADLINE_S / 2, f"committed {took:.1f} s after sending"
    reports = {u: seen.assignments[u] for u in survivors}
    if team[-1] in seen.assignments:  # it managed to commit before dying
        reports[team[-1]] = seen.assignments[team[-1]]
    first = next(iter(reports.values()))
    assert all(r.digest == first.digest and r.pairs == first.pairs for r in reports.values())
    assert set(map(int, first.pairs)) >= survivors


def test_late_joiner_catches_up_with_the_current_mission(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    seen, router = ground.seen, ground.router
    endpoints = ring_sim(fleet, tmp_path, 3)
    team = sorted(endpoints)
    for uav in team[:2]:
        fleet.onboard(uav, endpoints[uav], router)
    wait_for_telemetry(ground, team[:2])
    ground.send(MissionTargets(mission=1, team=tuple(team), targets=ring_targets(4, seed=9)))
    wait_until(lambda: set(team[:2]) <= set(seen.assignments), 30.0, "two assignments")
    # The third starts only now: it must learn the mission and fall in line.
    fleet.onboard(team[2], endpoints[team[2]], router)
    wait_until(lambda: team[2] in seen.assignments, 60.0, "the late joiner's assignment")
    late = seen.assignments[team[2]]
    assert late.mission == 1
    assert late.digest == seen.assignments[team[0]].digest
    assert late.target is None  # the others had committed without it


def test_a_uav_frozen_while_the_mission_was_sent_falls_in_line_when_it_resumes(
    fleet: Fleet, ground: Ground, tmp_path: Path
) -> None:
    seen = ground.seen
    team = start_ring(fleet, ground, tmp_path, 3)
    frozen = fleet.children[-1]
    assert frozen.name == f"onboard {team[-1]}"
    frozen.process.send_signal(signal.SIGSTOP)  # the fault: frozen before the mission
    try:
        mission = MissionTargets(
            mission=1, team=tuple(team), targets=ring_targets(3, seed=11), deadline_s=5.0
        )
        ground.send(mission)
        awake = set(team[:-1])
        wait_until(lambda: awake <= set(seen.assignments), 60.0, "the others' commitments")
        # It stays frozen past Zenoh's lease: the router drops its liveliness token.
        wait_until(
            lambda: not token_present(ground, SPACE.alive(team[-1])),
            FROZEN_S + 15.0,
            "the frozen UAV's token gone",
        )
    finally:
        frozen.process.send_signal(signal.SIGCONT)
    try:
        wait_until(lambda: team[-1] in seen.assignments, 60.0, "the resumed UAV's commitment")
    except AssertionError:
        for c in fleet.children:
            print("=====", c.name, *c.history[-60:], sep="\n")
        raise

    # Its teammates may re-plan once more as it comes back (it is counted back in): the
    # team falls in line when every UAV's latest commitment is the same plan.
    def one_plan() -> bool:
        return len({seen.assignments[u].digest for u in team}) == 1

    wait_until(one_plan, 60.0, "one plan for the whole team")
    resumed = seen.assignments[team[-1]]
    reference = seen.assignments[team[0]]
    assert resumed.mission == 1
    assert (resumed.digest, resumed.pairs) == (reference.digest, reference.pairs)
    assert resumed.target == reference.pairs.get(team[-1])
