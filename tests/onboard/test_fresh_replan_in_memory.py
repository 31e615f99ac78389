"""A re-plan from fresh times, on three real onboards and simulated autopilots in memory
(tests/support/memory_world.py): a holder stops after the commitment; every survivor
publishes its standing (its approach times from where it is now), and the team commits
one plan solved again from those times, not from the ones computed at the start."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, UavResult
from onboard.bus_edge import standing_selector
from tests.onboard.test_multi_uav_in_memory import PLANNING_SPEEDUP, ring, send
from tests.support.targets import ring_targets
from tests.support.waiting import wait_until

SPACE = KeySpace()


def test_a_re_plan_after_a_loss_is_solved_again_from_the_survivors_fresh_times(
    tmp_path: Path,
) -> None:
    with ring(tmp_path, 3, speedup=PLANNING_SPEEDUP) as (fleet, ground, seen):
        team = tuple(fleet.ids)
        send(ground, MissionTargets(mission=1, team=team, targets=ring_targets(3, seed=7)))
        wait_until(lambda: len(seen.assignments) == 3, 60.0, "three commitments")
        first = seen.assignments[team[0]]
        epoch0 = dict(seen.results)
        victim = max(first.pairs, key=lambda uav: first.arrivals[uav][-1])
        fleet.clock.set_speedup(10.0)  # the survivors fly on from where they planned
        wait_until(lambda: all(len(seen.telemetry.get(u, [])) > 20 for u in team), 30.0, "flight")
        fleet.stop_uav(victim)
        survivors = sorted(set(team) - {victim})

        def resolved() -> list[AssignmentReport]:
            with seen.lock:
                latest = [seen.assignments.get(uav) for uav in survivors]
            return [r for r in latest if r is not None and r.basis is not None]

        wait_until(lambda: len(resolved()) == 2, 60.0, "both survivors' resolved re-plan")
        plans = resolved()
        assert len({(r.digest, str(r.queues)) for r in plans}) == 1  # one plan
        plan = plans[0]
        assert plan.epoch == 1 and plan.released == (victim,)
        # Every target not reached is in exactly one survivor's queue, the orphan too.
        queued = [t for q in plan.queues.values() for t in q]
        assert len(queued) == len(set(queued)) and set(plan.queues) <= set(survivors)
        assert set(first.queues[victim]) <= set(queued) | set(plan.unserved)
        # Each survivor's first arrival is its standing's time, from where it was at the
        # loss: not the time it computed at the start.
        with seen.lock:
            heard = {uav: list(seen.standings.get(uav, [])) for uav in survivors}
        for uav, queue in plan.queues.items():
            (standing,) = [s for s in heard[uav] if s.basis == plan.basis]
            assert plan.arrivals[uav][0] == pytest.approx(standing.times[queue[0]])
            assert standing.times[queue[0]] != epoch0[uav].times[queue[0]]
            assert (standing.lat, standing.lon) != (epoch0[uav].lat, epoch0[uav].lon)
        # Each survivor's standing can be fetched by query, from the survivor itself, as
        # it put it (a restarted teammate or a ground that missed it): by the append
        # plan's digest; a plain query on a result key still gets the first result.
        ask = fleet.bus()
        for uav in survivors:
            key = SPACE.mission_result(1, uav)
            (fetched,) = ask.query_messages(standing_selector(key, plan.basis), UavResult, 2.0)
            assert fetched[0] == key and fetched[1].basis == plan.basis
            assert fetched[1] in heard[uav]
            ((_, result),) = ask.query_messages(key, UavResult, 2.0)
            assert result.basis is None and result == epoch0[uav]
