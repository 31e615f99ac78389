"""Real onboard cores say in their results whether they will propose for a mission
(`UavResult.proposes`): a mission naming a UAV that will not (started without
`--propose`, or without PyVRP) is decided as soon as every result is in, by every UAV
alike, not at the proposal window's end."""

from __future__ import annotations

from fleet.mission.messages import MissionTargets, UavResult
from fleet.mission.objective import Objective
from onboard.core import OnboardCore
from tests.onboard.core_harness import TARGETS, Recorder, make_core

TEAM = (74, 112)
WINDOW_S = 20.0


def _mission(proposers: tuple[int, ...]) -> MissionTargets:
    return MissionTargets(
        mission=1,
        team=TEAM,
        targets=TARGETS,
        objective=Objective.MIN_SUM,
        proposals_s=WINDOW_S,
        deadline_s=WINDOW_S + 10.0,
        proposers=proposers,
    )


def _results(out: Recorder) -> list[UavResult]:
    return [m for _, m in out.published if isinstance(m, UavResult)]


def _run_team(
    cores: dict[int, tuple[OnboardCore, Recorder]], mission: MissionTargets, end: float
) -> float | None:
    """Start `mission` on every core, pass each one's published results to the others,
    and tick until every core committed; the time they all had, None by `end`."""
    for uav, (core, _) in cores.items():
        for other in cores:
            if other != uav:
                core.on_alive(other, True, 0.0)
        core.on_targets(mission, 1.0)
    passed: set[tuple[int, int]] = set()
    now = 1.0
    while now < end:
        now += 0.25
        for uav, (core, out) in cores.items():
            core.tick(now)
            for result in _results(out):
                for other, (peer, _) in cores.items():
                    if other != uav and (other, result.uav) not in passed:
                        passed.add((other, result.uav))
                        peer.on_result(result, now)
        rounds = [core.round for core, _ in cores.values()]
        if all(r is not None and r.committed is not None for r in rounds):
            return now
    return None


def test_a_named_uav_not_started_to_propose_costs_no_window() -> None:
    cores = {74: make_core(uav=74), 112: make_core(uav=112)}
    decided = _run_team(cores, _mission((74,)), end=1.0 + WINDOW_S + 5.0)
    assert decided is not None and decided < 1.0 + WINDOW_S / 4
    (said,) = _results(cores[74][1])
    assert said.proposes is False
    digests = set()
    for core, _ in cores.values():
        assert core.round is not None and core.round.committed is not None
        digests.add(core.round.committed.digest)
    assert len(digests) == 1  # one plan, every UAV alike


def test_a_named_uav_without_its_solver_costs_no_window() -> None:
    """Started with `--propose`, but PyVRP not importable here: it says it will not."""
    cores = {74: make_core(uav=74, propose=True), 112: make_core(uav=112)}
    proposer = cores[74][0].mission.proposer
    assert proposer is not None
    proposer.solvable = False
    decided = _run_team(cores, _mission((74,)), end=1.0 + WINDOW_S + 5.0)
    assert decided is not None and decided < 1.0 + WINDOW_S / 4
    (said,) = _results(cores[74][1])
    assert said.proposes is False


def test_a_named_uav_that_will_propose_is_awaited() -> None:
    """Said it will propose, its proposal never comes (its solve is held here): the
    team waits to the window's end, as before."""
    cores = {74: make_core(uav=74, propose=True), 112: make_core(uav=112)}
    proposer = cores[74][0].mission.proposer
    assert proposer is not None
    proposer.solvable = True
    proposer.run = lambda work: None  # the solve never finishes
    decided = _run_team(cores, _mission((74,)), end=1.0 + WINDOW_S + 5.0)
    assert decided is not None and decided >= 1.0 + WINDOW_S
    (said,) = _results(cores[74][1])
    assert said.proposes is True


def test_a_mission_naming_no_uav_keeps_the_result_unsaid_and_the_grounds_wait() -> None:
    """Naming none, the mission takes the ground's plan only: the UAVs' results do not
    say (their digest is the one before the field) and the ground's plan is awaited."""
    cores = {74: make_core(uav=74, propose=True), 112: make_core(uav=112)}
    assert _run_team(cores, _mission(()), end=1.0 + WINDOW_S / 2) is None
    said = [r for _, out in cores.values() for r in _results(out)]
    assert len(said) == 2 and all(r.proposes is None for r in said)
