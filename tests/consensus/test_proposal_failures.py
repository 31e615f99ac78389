"""A proposal that fails changes nothing: results missing for the mission, PyVRP absent,
a candidate after the decision, an invalid candidate (an infinite leg among them), a
named proposer that never proposes. And a UAV's own proposer (onboard.plan_proposer):
it solves once it holds every team UAV's result, for a mission that names it only."""

from __future__ import annotations

import math
from typing import Any, cast

import msgspec
import pytest

from fleet.consensus.proposal import proposal_problem
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MISSION_MANAGER, MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from fleet.mission.status_kind import StatusKind
from fleet.solver.pyvrp_plan import SolverUnavailable
from ground.mission_follower import MissionFollower
from ground.propose import propose_when_results
from onboard.plan_proposer import PlanProposer
from tests.consensus.test_proposal import _inputs, _proposal, _round


class _Said:
    def __init__(self) -> None:
        self.said: list[tuple[StatusKind, str]] = []

    def __call__(self, kind: StatusKind, text: str, now: float, **_: Any) -> None:
        self.said.append((kind, text))


def _named(mission_round: Any, proposers: tuple[int, ...], window: float = 5.0) -> None:
    mission_round.targets = msgspec.structs.replace(
        mission_round.targets, proposers=proposers, proposals_s=window
    )


def _run_now(work: Any) -> None:
    work()


def test_an_infinite_leg_makes_a_candidate_invalid() -> None:
    times = {3: [100.0, 120.0, 130.0], 5: [110.0, 90.0, 140.0]}
    legs = [[0.0, 50.0, math.inf], [50.0, 0.0, 60.0], [math.inf, 60.0, 0.0]]
    proposal = PlanProposal(
        mission=9, proposer=5, digest="d", objective=Objective.MIN_SUM, queues={3: (0, 2), 5: (1,)}
    )
    why = proposal_problem(proposal, 9, Objective.MIN_SUM, "d", times, legs)
    assert why == "UAV 3's queue flies a leg no route flies"
    fine = msgspec.structs.replace(proposal, queues={3: (0,), 5: (1, 2)})
    assert proposal_problem(fine, 9, Objective.MIN_SUM, "d", times, legs) is None


def test_the_uavs_wait_for_every_named_proposer_within_the_window() -> None:
    mission_round = _round(3)
    _named(mission_round, (5, MISSION_MANAGER))
    assert mission_round.awaiting_proposal(1.0)
    mission_round.add_proposal(_proposal(mission_round))  # the ground's, valid
    assert mission_round.awaiting_proposal(1.0)  # UAV 5's still to come
    mission_round.add_proposal(_proposal(mission_round, proposer=5, queues={3: (0, 0)}))
    assert mission_round.awaiting_proposal(1.0)  # UAV 5's invalid: still waiting
    assert not mission_round.awaiting_proposal(5.0)  # the window closed: decide
    mission_round.add_proposal(_proposal(mission_round, proposer=5))
    assert not mission_round.awaiting_proposal(1.0)


def test_a_uav_proposes_as_itself_once_it_holds_every_result() -> None:
    pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
    said = _Said()
    proposer = PlanProposer(5, said, run=_run_now)
    mission_round = _round(5)
    _named(mission_round, (5,))
    proposal = proposer.tick(mission_round, 1.0)
    assert proposal is not None and proposal.proposer == 5 and proposal.mission == 9
    assert proposal.digest == _inputs(mission_round)
    used = {uav: r.times for uav, r in mission_round.results.items()}
    legs = mission_round.air_legs(used)
    assert proposal_problem(proposal, 9, Objective.MIN_SUM, proposal.digest, used, legs) is None
    assert proposer.tick(mission_round, 2.0) is None  # once a mission
    assert said.said == []


def test_a_uav_not_named_or_missing_results_proposes_nothing() -> None:
    calls: list[int] = []

    def solve(targets: MissionTargets, results: dict[int, UavResult], uav: int) -> PlanProposal:
        calls.append(uav)
        raise AssertionError("not to be solved")

    proposer = PlanProposer(5, _Said(), solve=solve, run=_run_now)
    not_named = _round(5)
    _named(not_named, (MISSION_MANAGER,))
    assert proposer.tick(not_named, 1.0) is None
    missing = _round(5)
    _named(missing, (5,))
    del missing.results[3]  # a teammate's result not heard yet
    assert proposer.tick(missing, 1.0) is None
    greedy = _round(5)
    _named(greedy, (5,))
    greedy.targets = msgspec.structs.replace(greedy.targets, objective=Objective.GREEDY)
    assert proposer.tick(greedy, 1.0) is None
    assert calls == []


def test_pyvrp_absent_is_said_and_the_baseline_decided() -> None:
    def solve(targets: MissionTargets, results: dict[int, UavResult], uav: int) -> PlanProposal:
        raise SolverUnavailable("PyVRP is not installed: pip install '.[solver]'")

    said = _Said()
    baseline = _round(5).decide({3, 5})
    mission_round = _round(5)
    _named(mission_round, (5,))
    assert PlanProposer(5, said, solve=solve, run=_run_now).tick(mission_round, 1.0) is None
    assert said.said == [
        (
            StatusKind.WARNING,
            "mission 9: no plan proposed: PyVRP is not installed: pip install '.[solver]'",
        )
    ]
    assert mission_round.ready(5.0, {3, 5})  # the window closes all the same
    report = mission_round.decide({3, 5})
    assert (report.queues, report.digest) == (baseline.queues, baseline.digest)


def test_a_proposal_solved_after_the_decision_is_not_put() -> None:
    pending: list[Any] = []
    proposer = PlanProposer(
        5,
        _Said(),
        solve=lambda targets, results, uav: _proposal(mission_round, proposer=uav),
        run=pending.append,
    )
    mission_round = _round(5)
    _named(mission_round, (5,))
    assert proposer.tick(mission_round, 1.0) is None  # solving
    baseline = mission_round.decide({3, 5})  # the window closed first
    pending.pop()()
    assert proposer.tick(mission_round, 6.0) is None
    assert not mission_round.add_proposal(_proposal(mission_round, proposer=5))
    assert mission_round.committed == baseline


class _Follower:
    """What `propose_when_results` asks of the ground's follower."""

    def __init__(self, results: dict[int, UavResult]) -> None:
        self.results = results

    def wait_until(self, done: Any, timeout_s: float, fetch_every_s: float) -> bool:
        return bool(done())

    def snapshot(self) -> tuple[dict[int, UavResult], dict[int, Any]]:
        return dict(self.results), {}


class _Bus:
    def __init__(self) -> None:
        self.put: list[tuple[str, object]] = []

    def publish(self, key: str, message: object) -> None:
        self.put.append((key, message))


def _ground_attempt(results: dict[int, UavResult]) -> tuple[Any, _Bus]:
    mission_round = _round(3, proposals_s=5.0)
    bus = _Bus()
    attempt = propose_when_results(
        cast(Any, bus), KeySpace(), mission_round.targets, cast(MissionFollower, _Follower(results))
    )
    return attempt, bus


def test_the_ground_proposes_nothing_without_every_result() -> None:
    results = dict(_round(3).results)
    del results[5]
    attempt, bus = _ground_attempt(results)
    assert (attempt.proposal, attempt.reason, bus.put) == (None, "results missing", [])


def test_the_ground_says_pyvrp_is_absent_and_puts_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    import ground.propose

    def absent(*_: object) -> PlanProposal:
        raise SolverUnavailable("PyVRP is not installed: pip install '.[solver]'")

    monkeypatch.setattr(ground.propose, "proposal_for", absent)
    attempt, bus = _ground_attempt(dict(_round(3).results))
    assert attempt.proposal is None and bus.put == []
    assert attempt.reason is not None and "pip install '.[solver]'" in attempt.reason


def test_a_named_proposer_outside_the_team_is_not_waited_for_nor_believed() -> None:
    """UAV 7 is named but not in the team (3, 5): it holds no round to solve from, so
    no UAV waits for it, and a proposal it signs is refused whatever it holds."""
    mission_round = _round(3)
    _named(mission_round, (7,))
    assert not mission_round.awaiting_proposal(1.0, {3, 5})
    assert mission_round.ready(1.0, {3, 5})  # decided at once, not at the window's end
    assert not mission_round.add_proposal(_proposal(mission_round, proposer=7))
    why = mission_round.right_problem(_proposal(mission_round, proposer=7))
    assert why == "UAV 7 is not in the mission's team (3, 5)"
    # Named with the ground: the ground's proposal is still waited for, not 7's.
    _named(mission_round, (7, MISSION_MANAGER))
    assert mission_round.awaiting_proposal(1.0, {3, 5})
    assert mission_round.add_proposal(_proposal(mission_round))
    assert not mission_round.awaiting_proposal(1.0, {3, 5})


def test_a_proposer_not_named_is_refused() -> None:
    mission_round = _round(3)
    _named(mission_round, (5,))
    for proposer in (3, MISSION_MANAGER):
        assert not mission_round.add_proposal(_proposal(mission_round, proposer=proposer))
    assert mission_round.right_problem(_proposal(mission_round, proposer=3)) == (
        "3 is not among the mission's proposers (5)"
    )
    assert not mission_round.proposals
    # A mission naming none takes the ground's proposal only.
    _named(mission_round, ())
    assert not mission_round.add_proposal(_proposal(mission_round, proposer=5))
    assert mission_round.add_proposal(_proposal(mission_round))


def test_a_gone_teammate_ends_the_wait_at_once_on_every_uav_alike() -> None:
    """UAV 5, the named proposer, is gone (no liveliness token): a decision without its
    result could adopt no proposal (each is solved from every team UAV's result, its
    digest says so), so UAV 3 decides at once, and what it decides is what it would
    have decided at the window's end."""
    mission_round = _round(3)
    _named(mission_round, (5,))
    assert mission_round.awaiting_proposal(1.0, {3, 5})  # 5 alive: its proposal awaited
    assert not mission_round.ready(1.0, {3, 5})
    assert not mission_round.awaiting_proposal(1.0, {3})  # 5 gone
    assert mission_round.ready(1.0, {3})
    early = mission_round.decide({3})
    late = _round(3)
    _named(late, (5,))
    assert late.ready(5.0, {3})  # the window closed
    assert late.add_proposal(_proposal(late, proposer=5))  # 5's, heard before the end
    full = late.decide({3})
    assert (early.digest, early.queues) == (full.digest, full.queues)
    assert "other results" in late.refused_proposals[5]


def test_a_gone_teammate_that_is_not_the_proposer_ends_the_wait_too() -> None:
    """Three UAVs, 5 the proposer, 8 gone: 5 solves from every team UAV's result, so no
    proposal of it can be a plan of the results 3 decides from."""
    mission_round = _round(3)
    _named(mission_round, (5,))
    mission_round.team = frozenset({3, 5, 8})
    assert not mission_round.awaiting_proposal(1.0, {3, 5})
    assert mission_round.awaiting_proposal(1.0, {3, 5, 8})  # 8 alive: its result may come


def _says(mission_round: Any, uav: int, proposes: bool | None) -> None:
    """`uav`'s result says whether it will propose (UavResult.proposes), heard again."""
    result = msgspec.structs.replace(mission_round.results[uav], proposes=proposes)
    assert mission_round.add_result(result)


def test_a_named_proposer_that_says_it_will_not_propose_is_not_waited_for() -> None:
    """UAV 5 is named and alive, but its result says it will not propose (started
    without `--propose`, or without PyVRP): every UAV holding that result decides as
    soon as every result is in, not at the window's end, and decides the same."""
    reports = []
    for own in (3, 5):
        mission_round = _round(own)
        _named(mission_round, (5,), window=20.0)
        _says(mission_round, 5, False)
        assert not mission_round.awaiting_proposal(1.0, {3, 5})
        assert mission_round.ready(1.0, {3, 5})  # at once, not at 20 s
        reports.append(mission_round.decide({3, 5}))
    first, second = reports
    assert (first.digest, first.queues) == (second.digest, second.queues)
    # Before 5's result (and its word) is in: not ready, the results come first.
    waiting = _round(3)
    _named(waiting, (5,), window=20.0)
    del waiting.results[5]
    assert not waiting.ready(1.0, {3, 5})


def test_a_named_proposer_that_says_it_will_propose_is_awaited_until_it_has() -> None:
    mission_round = _round(3)
    _named(mission_round, (5,), window=20.0)
    _says(mission_round, 5, True)
    assert mission_round.awaiting_proposal(1.0, {3, 5})
    assert not mission_round.ready(1.0, {3, 5})
    assert mission_round.add_proposal(_proposal(mission_round, proposer=5))
    assert not mission_round.awaiting_proposal(1.0, {3, 5})  # each awaited one proposed
    assert mission_round.ready(1.0, {3, 5})


def test_only_the_named_proposers_that_will_propose_are_awaited() -> None:
    """UAV 3 says it will not, UAV 5 that it will: 5's plan alone is awaited. With the
    ground named too, its plan is still awaited (it has no result to say otherwise)."""
    mission_round = _round(3)
    _named(mission_round, (3, 5), window=20.0)
    _says(mission_round, 3, False)
    _says(mission_round, 5, True)
    assert mission_round.awaiting_proposal(1.0, {3, 5})
    assert mission_round.add_proposal(_proposal(mission_round, proposer=5))
    assert not mission_round.awaiting_proposal(1.0, {3, 5})
    with_ground = _round(3)
    _named(with_ground, (5, MISSION_MANAGER), window=20.0)
    _says(with_ground, 5, False)
    assert with_ground.awaiting_proposal(1.0, {3, 5})  # the ground's plan
    assert with_ground.add_proposal(_proposal(with_ground))
    assert not with_ground.awaiting_proposal(1.0, {3, 5})
    # A mission naming none waits for the ground's plan whatever the results say.
    nobody = _round(3)
    _named(nobody, (), window=20.0)
    _says(nobody, 5, False)
    assert nobody.awaiting_proposal(1.0, {3, 5})


def test_a_result_that_does_not_say_keeps_the_wait() -> None:
    """An older UAV's result (no `proposes`): it may propose, so it is awaited."""
    mission_round = _round(3)
    _named(mission_round, (5,), window=20.0)
    _says(mission_round, 5, None)
    assert mission_round.awaiting_proposal(1.0, {3, 5})
    assert not mission_round.awaiting_proposal(20.0, {3, 5})  # the window's end


def test_what_a_result_says_of_proposing_is_digested() -> None:
    """Every UAV computes the same digest from the same word, and another from another:
    a UAV that heard a teammate say it will propose does not decide as one that heard it
    will not, under one digest. Unsaid, the digest is the one before the field."""
    digests = []
    for proposes in (None, False, True):
        mission_round = _round(3)
        _says(mission_round, 5, proposes)
        digests.append(_inputs(mission_round))
    assert len(set(digests)) == 3
    assert digests[0] == _inputs(_round(3))
