"""`ground-cli add-targets` and `remove-targets`: the mission changed in flight.

The ground reads the mission's latest revision as the UAVs serve it, puts the next one
(fleet.consensus.mission_change: added targets after the others, an index never
changes; removed targets never flown from then on), signed like every ground command,
and waits until each live team UAV acknowledges it: an assignment of that revision,
re-planned over what is left under the mission's objective. The page (`ground-cli gui`)
makes the same change through the same `change_mission`.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from contextlib import ExitStack
from dataclasses import dataclass
from typing import TextIO

from fleet.consensus.mission_change import next_revision
from fleet.consensus.report_checks import targets_problem
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport, MissionTargets, Target
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, OptionsError, fields_from
from ground.fleet_view import live_uav_ids
from ground.mission_control import MissionError, mission_targets_of, publish_targets
from ground.mission_follower import MissionFollower
from ground.mission_ids import current_mission_id
from ground.targets_command import read_or_say

#: How long a change waits for the team's acknowledgements by default (s).
ACK_WAIT_S = 10.0


@dataclass(frozen=True, kw_only=True)
class ChangeOptions(BusOptions):
    #: The mission (None: the latest seen).
    mission: int | None = None
    #: How long to wait for every live team UAV to acknowledge the change.
    timeout: float = ACK_WAIT_S
    json: bool = False


@dataclass(frozen=True, kw_only=True)
class AddOptions(ChangeOptions):
    #: The targets to add, read and checked (`add_options` reads them from the file).
    targets: tuple[Target, ...]
    file: str = "targets"


@dataclass(frozen=True, kw_only=True)
class RemoveOptions(ChangeOptions):
    #: The indexes of the targets to remove.
    indexes: tuple[int, ...]


def add_options(args: argparse.Namespace) -> AddOptions:
    """The options of `add-targets`, its file read and checked first: a bad file sends
    nothing."""
    read = read_or_say(args.file, "nothing sent")
    if read is None:
        raise OptionsError("", ExitCode.FAILED)
    return fields_from(AddOptions, args, targets=tuple(read))


def remove_options(args: argparse.Namespace) -> RemoveOptions:
    return fields_from(RemoveOptions, args, indexes=tuple(args.indexes))


def run_add_targets(bus: Bus, options: AddOptions, out: TextIO) -> int:
    return _change(bus, options, out, added=options.targets, removed=())


def run_remove_targets(bus: Bus, options: RemoveOptions, out: TextIO) -> int:
    return _change(bus, options, out, added=(), removed=options.indexes)


class ChangeRefused(MissionError):
    """A change that cannot be made (no such mission, a bad index or target); nothing
    was sent. Its text says why."""


@dataclass(frozen=True)
class MissionChange:
    """A change put on the bus, and who acknowledged it."""

    new: MissionTargets  #: the revision put
    added: list[int]  #: the indexes of the targets added
    removed: list[int]  #: the indexes removed by this change
    acked: list[int]  #: the live team UAVs that planned this revision
    missing: list[int]  #: the live team UAVs that did not within the wait
    reports: dict[int, AssignmentReport]  #: each UAV's latest plan heard
    timeout_s: float

    @property
    def acknowledged(self) -> bool:
        return not self.missing

    def summary(self) -> str:
        """One line: what changed, and who acknowledged it (or who did not)."""
        what = []
        if self.added:
            what.append(f"{_targets(self.added)} added")
        if self.removed:
            what.append(f"{_targets(self.removed)} removed")
        head = f"mission {self.new.mission} revision {self.new.revision}: {'; '.join(what)}"
        if self.missing:
            return (
                f"{head}; not acknowledged by {', '.join(map(str, self.missing))} within "
                f"{self.timeout_s:g} s"
            )
        return f"{head}; acknowledged by {', '.join(map(str, self.acked)) or 'no UAV'}"


def _targets(indexes: list[int]) -> str:
    return f"target{'s' if len(indexes) > 1 else ''} {', '.join(map(str, indexes))}"


@dataclass
class ChangePut:
    """A change put on the bus (`put_change`), its acknowledgements awaited by `wait`;
    close it (or leave its `with`) to stop following them."""

    stack: ExitStack
    follower: MissionFollower
    held: MissionTargets
    new: MissionTargets
    removed: tuple[int, ...]
    expected: list[int]

    def wait(self, timeout_s: float, stop: threading.Event | None = None) -> MissionChange:
        """Wait up to `timeout_s` for every live team UAV to plan the revision (`stop`
        set: no longer, within a second)."""
        follower, new, expected = self.follower, self.new, self.expected
        stopped = stop or threading.Event()

        def acknowledged() -> bool:
            if stopped.is_set():
                return True
            return all(_acks(follower.assignments.get(uav), new) for uav in expected)

        follower.wait_until(acknowledged, timeout_s, fetch_every_s=1.0)
        _, reports = follower.snapshot()
        acked = [uav for uav in expected if _acks(reports.get(uav), new)]
        return MissionChange(
            new=new,
            added=list(range(len(self.held.targets), len(new.targets))),
            removed=list(self.removed),
            acked=acked,
            missing=[uav for uav in expected if uav not in acked],
            reports=reports,
            timeout_s=timeout_s,
        )

    def close(self) -> None:
        self.stack.close()

    def __enter__(self) -> ChangePut:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def put_change(
    bus: Bus,
    space: KeySpace,
    mission: int | None,
    *,
    added: tuple[Target, ...],
    removed: tuple[int, ...],
    query_timeout_s: float = 1.0,
) -> ChangePut:
    """Put mission `mission`'s next revision (None: the latest mission seen), following
    the team's plans from before the put. ChangeRefused, with the reason, when nothing
    was sent. Blocking (Zenoh queries): the page runs it off its loop."""
    if mission is None:
        mission = current_mission_id(bus, space, query_timeout_s)
    if mission is None:
        raise ChangeRefused("no mission seen (give --mission); nothing sent")
    try:
        held = mission_targets_of(bus, space, mission, query_timeout_s)
        new = next_revision(held, added, removed)
    except (MissionError, ValueError) as error:
        raise ChangeRefused(f"mission {mission}: {error}; nothing sent") from None
    problem = targets_problem(new)
    if problem is not None:
        raise ChangeRefused(f"mission {mission}: {problem}; nothing sent")
    live = set(live_uav_ids(bus, space, query_timeout_s))
    expected = sorted(uav for uav in new.team if uav in live)
    stack = ExitStack()
    try:
        follower = stack.enter_context(MissionFollower(bus, space, mission, team=new.team))
        publish_targets(bus, space, new)
    except BaseException:
        stack.close()
        raise
    return ChangePut(stack, follower, held, new, removed, expected)


def change_mission(
    bus: Bus,
    space: KeySpace,
    mission: int | None,
    *,
    added: tuple[Target, ...],
    removed: tuple[int, ...],
    timeout_s: float = ACK_WAIT_S,
    query_timeout_s: float = 1.0,
) -> MissionChange:
    """Put the change (`put_change`) and wait up to `timeout_s` for every live team UAV
    to plan it."""
    put = put_change(
        bus, space, mission, added=added, removed=removed, query_timeout_s=query_timeout_s
    )
    with put:
        return put.wait(timeout_s)


def _change(
    bus: Bus,
    options: ChangeOptions,
    out: TextIO,
    *,
    added: tuple[Target, ...],
    removed: tuple[int, ...],
) -> int:
    try:
        change = change_mission(
            bus,
            options.key_space,
            options.mission,
            added=added,
            removed=removed,
            timeout_s=options.timeout,
            query_timeout_s=options.query_timeout,
        )
    except ChangeRefused as error:
        print(f"error: {error}", file=sys.stderr)
        return ExitCode.FAILED
    _say(out, options.json, change)
    if change.missing:
        new = change.new
        print(
            f"error: mission {new.mission} revision {new.revision}: not acknowledged by "
            f"{', '.join(map(str, change.missing))} within {options.timeout:g} s",
            file=sys.stderr,
        )
        return ExitCode.FAILED
    return ExitCode.OK


def _acks(report: AssignmentReport | None, new: MissionTargets) -> bool:
    return report is not None and report.revision >= new.revision


def queues_of(change: MissionChange) -> dict[str, list[int]]:
    """The queues of the revision as the first UAV that acknowledged it planned them."""
    first = change.reports[change.acked[0]] if change.acked else None
    return {str(u): list(q) for u, q in first.queues.items()} if first is not None else {}


def _say(out: TextIO, as_json: bool, change: MissionChange) -> None:
    new = change.new
    queues = queues_of(change)
    if as_json:
        print(
            json.dumps(
                {
                    "mission": new.mission,
                    "revision": new.revision,
                    "added": change.added,
                    "removed": change.removed,
                    "acknowledged": change.acked,
                    "not_acknowledged": change.missing,
                    "queues": queues,
                }
            ),
            file=out,
        )
        return
    what = []
    if change.added:
        what.append(f"targets {', '.join(map(str, change.added))} added")
    if change.removed:
        what.append(f"targets {', '.join(map(str, change.removed))} removed")
    print(f"mission {new.mission} revision {new.revision}: {'; '.join(what)}", file=out)
    print(f"acknowledged by {', '.join(map(str, change.acked)) or 'no UAV'}", file=out)
    for name, queue in queues.items():
        print(f"  UAV {name}: {', '.join(map(str, queue)) or 'no target'}", file=out)


ADD_TARGETS = Command(add_options, run_add_targets)
REMOVE_TARGETS = Command(remove_options, run_remove_targets)
