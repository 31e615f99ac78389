"""`ground-cli mission` and `abort`: a mission's status now, and ending it."""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from typing import TextIO

from fleet.mission.key_space import KeySpace
from fleet.mission.phase import Phase
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, options_from
from ground.fleet_view import query_states
from ground.mission_control import MissionError, mission_status, mission_targets_of, send_abort
from ground.mission_ids import current_mission_id, missions_seen
from ground.mission_summary import summary_lines, unreached_lines

#: How long `abort` waits for every UAV on the mission to report it aborted.
ABORT_CONFIRM_S = 5.0


@dataclass(frozen=True, kw_only=True)
class MissionOptions(BusOptions):
    #: The mission (None: the latest seen).
    mission: int | None = None
    #: First wait up to this long for every target to be reached; exit 0 only if so.
    until_reached: float | None = None
    json: bool = False


def run_mission(bus: Bus, options: MissionOptions, out: TextIO) -> int:
    mission = options.mission
    if mission is None:
        mission = current_mission_id(bus, options.key_space, options.query_timeout)
    if mission is None:
        print("error: no mission seen (give --mission)", file=sys.stderr)
        return ExitCode.FAILED
    try:
        outcome = mission_status(
            bus, options.key_space, mission, options.query_timeout, options.until_reached
        )
    except MissionError as error:
        print(f"error: {error}", file=sys.stderr)
        return ExitCode.FAILED
    if options.json:
        print(json.dumps(outcome.to_json()), file=out)
    else:
        print("\n".join(summary_lines(outcome)), file=out)
    if options.until_reached is not None:
        missing = unreached_lines(outcome)
        if missing:
            print(
                f"error: mission {mission}: not every target reached within "
                f"{options.until_reached:g} s:",
                file=sys.stderr,
            )
            print("\n".join(missing), file=sys.stderr)
            return ExitCode.FAILED
        return ExitCode.OK
    return ExitCode.OK if outcome.succeeded else ExitCode.FAILED


@dataclass(frozen=True, kw_only=True)
class AbortOptions(BusOptions):
    #: The mission (None: the latest seen).
    mission: int | None = None
    #: Abort this UAV alone; its teammates fly on (None: the whole team).
    uav: int | None = None


def run_abort(bus: Bus, options: AbortOptions, out: TextIO) -> int:
    seen = missions_seen(bus, options.key_space, options.query_timeout)
    mission = options.mission
    if mission is None:
        mission = max(seen, default=None)
        if mission is None:
            print("error: no mission to abort (none seen; give --mission)", file=sys.stderr)
            return ExitCode.FAILED
    elif mission not in seen:
        known = ", ".join(map(str, sorted(seen))) or "none"
        print(
            f"error: mission {mission} is unknown to the fleet (missions seen: {known}); "
            "nothing sent",
            file=sys.stderr,
        )
        return ExitCode.FAILED
    send_abort(bus, options.key_space, mission, options.uav)
    to = "" if options.uav is None else f" to UAV {options.uav}"
    print(f"mission {mission}: abort sent{to}", file=out, flush=True)
    return _confirm_abort(bus, options.key_space, mission, options.uav, options.query_timeout, out)


def _confirm_abort(
    bus: Bus, space: KeySpace, mission: int, uav: int | None, timeout_s: float, out: TextIO
) -> int:
    """Wait until every UAV aborted (the mission's team, or `uav` alone) reports it.

    A team UAV that does not answer at all (frozen, cut off) has not confirmed: it is
    named, and the exit code says so.
    """
    deadline = time.monotonic() + max(ABORT_CONFIRM_S, timeout_s)
    try:
        team = set(mission_targets_of(bus, space, mission, timeout_s).team)
    except MissionError:
        team = set()  # nobody serves the targets: judge by the states alone
    expected = {uav} if uav is not None else team
    pending: dict[int, str] = {}
    while True:
        states = query_states(bus, space, timeout_s)
        on_mission = {
            piccolo_id
            for piccolo_id, state in states.items()
            if state.mission is not None
            and state.mission.mission == mission
            and (uav is None or piccolo_id == uav)
        }
        pending = {
            piccolo_id: str(state.mission.phase)
            for piccolo_id, state in states.items()
            if piccolo_id in on_mission
            and state.mission is not None
            and state.mission.phase != Phase.ABORTED
        }
        # A team UAV that left for a later mission is off this one; a silent one is not.
        silent = expected - states.keys()
        pending.update({piccolo_id: "no answer" for piccolo_id in silent})
        if not pending or time.monotonic() >= deadline:
            break
        time.sleep(0.2)  # polling the UAVs' state: each query is itself an observation
    confirmed = sorted(on_mission - set(pending))
    print(f"mission {mission}: aborted by {', '.join(map(str, confirmed)) or 'no UAV'}", file=out)
    if uav is not None and uav not in on_mission and uav not in pending:
        print(f"error: UAV {uav} is not on mission {mission}", file=sys.stderr)
        return ExitCode.FAILED
    if pending:
        still = ", ".join(f"{p} ({phase})" for p, phase in sorted(pending.items()))
        print(f"error: mission {mission}: not confirmed by {still}", file=sys.stderr)
        return ExitCode.FAILED
    return ExitCode.OK


MISSION = Command(options_from(MissionOptions), run_mission)
ABORT = Command(options_from(AbortOptions), run_abort)
