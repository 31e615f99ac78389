"""`ground-cli add-targets` and `remove-targets`: the mission changed in flight.

The ground reads the mission's latest revision as the UAVs serve it, puts the next one
(fleet.consensus.mission_change: added targets after the others, an index never
changes; removed targets never flown from then on), signed like every ground command,
and waits until each live team UAV acknowledges it: an assignment of that revision,
re-planned over what is left under the mission's objective.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from typing import TextIO

from fleet.consensus.mission_change import next_revision
from fleet.consensus.report_checks import targets_problem
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


def _change(
    bus: Bus,
    options: ChangeOptions,
    out: TextIO,
    *,
    added: tuple[Target, ...],
    removed: tuple[int, ...],
) -> int:
    space, timeout = options.key_space, options.query_timeout
    mission = options.mission
    if mission is None:
        mission = current_mission_id(bus, space, timeout)
    if mission is None:
        print("error: no mission seen (give --mission); nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    try:
        held = mission_targets_of(bus, space, mission, timeout)
        new = next_revision(held, added, removed)
    except (MissionError, ValueError) as error:
        print(f"error: mission {mission}: {error}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    problem = targets_problem(new)
    if problem is not None:
        print(f"error: mission {mission}: {problem}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    live = set(live_uav_ids(bus, space, timeout))
    expected = sorted(uav for uav in new.team if uav in live)
    with MissionFollower(bus, space, mission, team=new.team) as follower:
        publish_targets(bus, space, new)

        def acknowledged() -> bool:
            return all(_acks(follower.assignments.get(uav), new) for uav in expected)

        follower.wait_until(acknowledged, options.timeout, fetch_every_s=1.0)
        _, reports = follower.snapshot()
    acked = [uav for uav in expected if _acks(reports.get(uav), new)]
    missing = [uav for uav in expected if uav not in acked]
    first_added = len(held.targets)
    added_indexes = list(range(first_added, len(new.targets)))
    _say(out, options.json, new, added_indexes, list(removed), acked, missing, reports)
    if missing:
        print(
            f"error: mission {mission} revision {new.revision}: not acknowledged by "
            f"{', '.join(map(str, missing))} within {options.timeout:g} s",
            file=sys.stderr,
        )
        return ExitCode.FAILED
    return ExitCode.OK


def _acks(report: AssignmentReport | None, new: MissionTargets) -> bool:
    return report is not None and report.revision >= new.revision


def _say(
    out: TextIO,
    as_json: bool,
    new: MissionTargets,
    added: list[int],
    removed: list[int],
    acked: list[int],
    missing: list[int],
    reports: dict[int, AssignmentReport],
) -> None:
    first = reports[acked[0]] if acked else None
    queues = {str(u): list(q) for u, q in first.queues.items()} if first is not None else {}
    if as_json:
        print(
            json.dumps(
                {
                    "mission": new.mission,
                    "revision": new.revision,
                    "added": added,
                    "removed": removed,
                    "acknowledged": acked,
                    "not_acknowledged": missing,
                    "queues": queues,
                }
            ),
            file=out,
        )
        return
    what = []
    if added:
        what.append(f"targets {', '.join(map(str, added))} added")
    if removed:
        what.append(f"targets {', '.join(map(str, removed))} removed")
    print(f"mission {new.mission} revision {new.revision}: {'; '.join(what)}", file=out)
    print(f"acknowledged by {', '.join(map(str, acked)) or 'no UAV'}", file=out)
    for name, queue in queues.items():
        print(f"  UAV {name}: {', '.join(map(str, queue)) or 'no target'}", file=out)


ADD_TARGETS = Command(add_options, run_add_targets)
REMOVE_TARGETS = Command(remove_options, run_remove_targets)
