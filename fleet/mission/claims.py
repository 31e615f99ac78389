"""What a UAV's signed message proves, and what it only hints at.

In the secure profile every outcome is signed by the UAV it is about (the key names it,
`fleet.mission.signature`), so it proves what that UAV says of *itself*: that it
reached its own targets, or dropped out. What it says of a teammate (the `reached`
entries naming another UAV, kept there so that a ground joining late learns what a lost
UAV had reached) is only hearsay: a captured aircraft could list its teammates' targets
as reached, and each teammate would skip them and re-sign the lie. So a claim about
another UAV is a *hint*: a reason to fetch that UAV's own signed outcome (relayed
verbatim by whoever holds it), never a fact.

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable

from fleet.mission.messages import TargetOutcome
from fleet.mission.phase import Phase


def own_claims(outcome: TargetOutcome) -> dict[int, int]:
    """Target -> its UAV, for each target the outcome's own UAV says it reached."""
    own = {target: uav for target, uav in outcome.reached.items() if uav == outcome.uav}
    if outcome.phase == Phase.REACHED and outcome.target is not None:
        own.setdefault(outcome.target, outcome.uav)
    return own


def hints(outcome: TargetOutcome) -> dict[int, int]:
    """Target -> UAV for each target the outcome says *another* UAV reached: not believed
    until that UAV's own outcome says so."""
    return {target: uav for target, uav in outcome.reached.items() if uav != outcome.uav}


def reached_by(outcomes: Iterable[TargetOutcome]) -> dict[int, int]:
    """Target -> the UAV that reached it, each believed from that UAV's own outcome only
    (the lowest Piccolo ID first, should two claim one target)."""
    reached: dict[int, int] = {}
    for outcome in sorted(outcomes, key=lambda o: o.uav):
        for target, uav in own_claims(outcome).items():
            reached.setdefault(target, uav)
    return reached


def flown_by(outcomes: Iterable[TargetOutcome]) -> dict[int, list[int]]:
    """Target -> every UAV whose own outcome says it reached it (ascending): two or more
    flew it (a partition, a finished UAV's outcome that spread late)."""
    flown: dict[int, set[int]] = {}
    for outcome in outcomes:
        for target, uav in own_claims(outcome).items():
            flown.setdefault(target, set()).add(uav)
    return {target: sorted(uavs) for target, uavs in sorted(flown.items())}


def unconfirmed(outcomes: Iterable[TargetOutcome]) -> set[int]:
    """The UAVs named in a hint that their own outcomes (as held) do not back: whose own
    outcome to fetch."""
    held = list(outcomes)
    proven = reached_by(held)
    return {
        uav
        for outcome in held
        for target, uav in hints(outcome).items()
        if proven.get(target) != uav
    }


def newer(held: TargetOutcome | None, heard: TargetOutcome) -> bool:
    """Whether `heard` (the same UAV's outcome) may replace `held`: a UAV's later outcome
    lists every target it reached before, so one that claims less is an older copy (a
    relay that missed the latest)."""
    if held is None:
        return True
    mine, theirs = own_claims(held).keys(), own_claims(heard).keys()
    return not theirs < mine
