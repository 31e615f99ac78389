"""`ground-cli send-targets`: Send Targets (thesis 3.1.4), and follow the mission.

The file is read and checked first; then a mission id is claimed (`claim_mission`), the
targets are put, and the mission is followed: to its commitments with --wait, else
until the team acknowledges receipt (at most `DELIVERY_WAIT_S`).
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
from dataclasses import dataclass
from typing import TextIO

from fleet.consensus.deadline import consensus_deadline
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MISSION_MANAGER,
    AssignmentReport,
    MissionTargets,
    NoFlyZone,
    PlanProposal,
    Target,
    TargetOutcome,
    UavResult,
)
from fleet.mission.objective import Objective
from fleet.mission.target_checks import DEFAULT_MAX_REACH_M, target_set_problems
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, OptionsError, fields_from
from ground.fleet_view import live_uav_ids, query_states
from ground.mission_ack import MissionCollision, acknowledgement, wait_acknowledged
from ground.mission_control import MissionError, publish_targets
from ground.mission_follower import Listener, MissionFollower
from ground.mission_ids import TargetsServer, claim_mission, contest_grace_s
from ground.mission_outcome import MissionOutcome, check_agreement
from ground.mission_summary import summary_lines
from ground.proposals_heard import declined, heard_proposals
from ground.propose import named_proposers, proposal_window, propose_when_results
from ground.targets_command import read_or_say
from ground.zones_command import zones_or_say

#: How long `send-targets` without --wait waits for the team to acknowledge receipt.
DELIVERY_WAIT_S = 3.0


def _progress_printer(out: TextIO, team: tuple[int, ...]) -> Listener:
    """Prints each result and commitment as it arrives, with the count so far.

    Once every team UAV has committed, says whether they agree (same digest and pairs).
    """
    # Results and reports arrive on Zenoh threads, possibly two at once.
    lock = threading.Lock()
    results: set[int] = set()
    reports: dict[int, AssignmentReport] = {}

    def on_message(kind: str, message: UavResult | AssignmentReport | TargetOutcome) -> None:
        with lock:
            if isinstance(message, UavResult):
                results.add(message.uav)
                times = ", ".join("-" if t is None else f"{t:.1f}" for t in message.times)
                lines = [
                    f"mission {message.mission}: UAV {message.uav} result: [{times}] s "
                    f"({len(results & set(team))}/{len(team)} results)"
                ]
            elif isinstance(message, TargetOutcome):
                why = f" ({message.reason})" if message.reason else ""
                lines = [
                    f"mission {message.mission}: UAV {message.uav} {message.phase} "
                    f"target {message.target}{why}"
                ]
            else:
                reports[message.uav] = message
                target = "none" if message.target is None else str(message.target)
                eta = "" if message.eta_s is None else f", ETA {message.eta_s:.0f} s"
                queue = message.queues.get(message.uav, ())
                if len(queue) > 1:
                    eta += f", then {', '.join(map(str, queue[1:]))}"
                lines = [
                    f"mission {message.mission}: UAV {message.uav} committed target "
                    f"{target}{eta}, digest {message.digest[:12]} "
                    f"({len(reports.keys() & set(team))}/{len(team)} committed)"
                ]
                agreement = check_agreement(team, reports)
                if not agreement.missing:
                    verdict = "agree" if agreement.agreed else "DISAGREE"
                    lines.append(f"mission {message.mission}: every UAV committed: they {verdict}")
            print("\n".join(lines), file=out, flush=True)

    return on_message


@dataclass(frozen=True, kw_only=True)
class SendOptions(BusOptions):
    """What `send-targets` sends and how it follows it."""

    #: The targets, read and checked (`send_options` reads them from the file).
    targets: tuple[Target, ...]
    #: Where they came from, as the messages name it.
    file: str = "targets"
    #: The no-fly zones, checked against the targets.
    zones: tuple[NoFlyZone, ...] = ()
    #: The team (None: every live UAV).
    team: tuple[int, ...] | None = None
    #: Follow the mission until every UAV has committed, then watch for a rival.
    wait: bool = False
    #: How long --wait waits.
    timeout: float = 60.0
    #: How long each UAV waits for its teammates' results (None: by the team's size).
    deadline: float | None = None
    #: The mission id (None: one more than the highest seen).
    mission: int | None = None
    max_reach_km: float = DEFAULT_MAX_REACH_M / 1000.0
    #: Send all the same a set that fails the checks, or to a team UAV not live.
    force: bool = False
    objective: Objective = Objective.GREEDY
    #: Propose a plan solved by PyVRP (ground.propose) once the results are in.
    propose: bool = False
    #: UAVs that propose a plan (their onboards started with --propose).
    proposers: tuple[int, ...] = ()
    json: bool = False


def send_options(args: argparse.Namespace) -> SendOptions:
    """The options of `send-targets`, its files read and checked first: a bad file sends
    nothing, and is said before anything touches the network."""
    read = read_or_say(args.file, "nothing sent")
    if read is None:
        raise OptionsError("", ExitCode.FAILED)
    targets = tuple(read)
    zones = zones_or_say(args.no_fly, targets)
    if zones is None:
        raise OptionsError("", ExitCode.FAILED)
    return fields_from(SendOptions, args, targets=targets, zones=zones)


def run_send_targets(bus: Bus, options: SendOptions, out: TextIO) -> int:
    progress = sys.stderr if options.json else out
    team = _team(bus, options)
    if not team:
        if not options.team:
            print("error: no live UAV to send to (name the team with --team)", file=sys.stderr)
        return ExitCode.FAILED

    if not _targets_pass_checks(bus, options, team):
        return ExitCode.FAILED
    deadline_s = options.deadline or consensus_deadline(len(team))
    proposals_s = 0.0
    # Named when UAVs propose: the UAVs then wait for each one's proposal (within the
    # window), so that they all choose among the same ones.
    try:
        proposers = named_proposers(options.propose, options.proposers, team)
    except ValueError as error:
        print(f"error: {error}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    if options.propose or options.proposers:
        if options.objective is Objective.GREEDY:
            flag = "--propose" if options.propose else "--proposers"
            print(f"error: {flag} needs --objective min-sum or min-max", file=sys.stderr)
            return ExitCode.FAILED
        deadline_s, proposals_s = proposal_window(options.objective, deadline_s)

    def make(mission: int) -> MissionTargets:
        return MissionTargets(
            mission,
            team,
            options.targets,
            deadline_s=deadline_s,
            zones=options.zones,
            objective=options.objective,
            proposals_s=proposals_s,
            proposers=proposers,
        )

    try:
        with claim_mission(
            bus, options.key_space, make, options.query_timeout, mission=options.mission
        ) as server:
            outcome = _send_and_follow(bus, server, options, progress)
    except MissionCollision as error:
        print(f"error: {error}", file=sys.stderr)
        return ExitCode.FAILED
    except MissionError as error:
        print(f"error: {error}; nothing sent", file=sys.stderr)
        return ExitCode.FAILED
    if options.json:
        data = outcome.to_json() | outcome.proposals_json()
        if options.proposers:
            data.setdefault("uav_proposals", {})
        print(json.dumps(data), file=out)
    elif options.wait:
        print("\n".join(summary_lines(outcome)), file=out)
    if not options.wait:
        return ExitCode.OK
    return ExitCode.OK if outcome.succeeded else ExitCode.FAILED


def _send_and_follow(
    bus: Bus, server: TargetsServer, options: SendOptions, progress: TextIO
) -> MissionOutcome:
    """Put the claimed mission and, with --wait, follow it to its commitments and then
    for as long as a rival ground's later mission may take (`_watch_for_rival`)."""
    message = server.targets
    mission, team, targets = message.mission, message.team, message.targets
    listener = _progress_printer(progress, team) if options.wait else None
    outcome = MissionOutcome(mission=mission, team=team, targets=targets, zones=message.zones)
    # A change in flight (`add-targets`, the page) is served from then on: a UAV that
    # joins late fetches the mission as it is, not as it was sent.
    with MissionFollower(
        bus, options.key_space, mission, listener, team, on_revision=server.revise
    ) as follower:
        publish_targets(bus, options.key_space, message)
        print(
            f"mission {mission}: {len(targets)} targets from {options.file}"
            + (f" and {len(message.zones)} no-fly zones" if message.zones else "")
            + " sent to "
            f"{', '.join(map(str, team))}",
            file=progress,
            flush=True,
        )
        proposal = _propose(bus, options, message, follower, progress) if options.propose else None
        if options.wait:
            committed = follower.wait_committed(team, options.timeout, fetch_every_s=1.0)
            outcome.timed_out = not committed and follower.superseded_by is None
            if committed:
                # The commitments heard are for this id: they must be for these targets.
                seen = acknowledgement(bus, options.key_space, message, options.query_timeout)
                if (collision := seen.collision(message)) is not None:
                    raise collision
                _watch_for_rival(follower, server, options.query_timeout, progress)
        else:
            _report_delivery(
                bus, options.key_space, message, min(DELIVERY_WAIT_S, options.timeout), progress
            )
        follower.fetch(options.query_timeout)
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
        outcome.lost = set(follower.lost) & set(team)
        if options.wait:
            _read_phases(bus, options.key_space, outcome, follower, options.query_timeout)
        if options.wait and (proposal is not None or options.proposers):
            _judge_proposals(message, follower, proposal, outcome, progress)
    return outcome


def _judge_proposals(
    message: MissionTargets,
    follower: MissionFollower,
    proposal: PlanProposal | None,
    outcome: MissionOutcome,
    progress: TextIO,
) -> None:
    """Each proposal heard (this ground's own `proposal` as it was put), checked as the
    UAVs check it, and what the UAVs' first plans say of it: their reported digests,
    nothing else (`ground.proposals_heard`, as the page shows them)."""
    mission = message.mission
    proposals = follower.proposal_snapshot()
    if proposal is not None:
        proposals[MISSION_MANAGER] = proposal
    heard = heard_proposals(message, outcome.results, proposals, outcome.assignments.values())
    for seen in heard:
        if seen.proposer == MISSION_MANAGER:
            outcome.proposal = seen
            print(f"mission {mission}: the ground's proposal: {seen.summary()}", file=progress)
        else:
            outcome.uav_proposals[seen.proposer] = seen
            said = seen.summary()
            print(f"mission {mission}: UAV {seen.proposer}'s proposal: {said}", file=progress)
    said_no = declined(message, outcome.results)
    for uav in sorted(set(message.proposers) - proposals.keys() - {MISSION_MANAGER}):
        why = " (its result said it will not propose: not waited for)" if uav in said_no else ""
        print(f"mission {mission}: no proposal heard from UAV {uav}{why}", file=progress)


def _propose(
    bus: Bus,
    options: SendOptions,
    message: MissionTargets,
    follower: MissionFollower,
    progress: TextIO,
) -> PlanProposal | None:
    """Wait for the team's results (within the proposal window), then solve and publish
    the ground's proposal; said on `progress` either way."""
    attempt = propose_when_results(bus, options.key_space, message, follower)
    proposal = attempt.proposal
    if proposal is None:
        print(f"mission {message.mission}: no plan proposed: {attempt.reason}", file=progress)
        return None
    queues = ", ".join(f"{uav}: {list(q)}" for uav, q in proposal.queues.items())
    print(
        f"mission {message.mission}: plan proposed ({attempt.cpu_s or 0.0:.2f} s of CPU): {queues}",
        file=progress,
        flush=True,
    )
    return proposal


def _watch_for_rival(
    follower: MissionFollower, server: TargetsServer, query_timeout_s: float, out: TextIO
) -> None:
    """After the team committed, watch for a later mission of the team for as long as
    another ground started about together with this one may take to send it.

    A team commits a small mission in tens of milliseconds, before a ground started a
    moment later has even chosen its id (it then chooses a higher one, so the ids need
    not collide): without this watch both grounds would report success while the team
    flies only the later mission.
    """
    mission = follower.mission
    grace = contest_grace_s(query_timeout_s)
    rival = "another ground chose this id too" if server.contested.is_set() else "committed"
    print(
        f"mission {mission}: {rival}; watching {grace:g} s for a later mission",
        file=out,
        flush=True,
    )
    follower.wait_superseded(grace, fetch_every_s=1.0)


def _team(bus: Bus, options: SendOptions) -> tuple[int, ...]:
    """`--team`, or every live UAV; () when a named member is not live (said why), unless
    --force, when it is warned about: the mission waits for it, which may be forever."""
    live = live_uav_ids(bus, options.key_space, options.query_timeout)
    if not options.team:
        return tuple(live)
    absent = ", ".join(str(uav) for uav in options.team if uav not in live)
    why = "no liveliness token, or none its UAV's own signed state vouches for"
    if absent and not options.force:
        print(
            f"error: not live now: {absent} ({why if bus.signed else 'no liveliness token'}); "
            "nothing sent (--force "
            "sends to them all the same: a UAV that comes up fetches the mission)",
            file=sys.stderr,
        )
        return ()
    if absent:
        print(
            f"warning: not live now: {absent}; they can fetch the mission when they come up",
            file=sys.stderr,
        )
    return tuple(options.team)


def _targets_pass_checks(bus: Bus, options: SendOptions, team: tuple[int, ...]) -> bool:
    """The set's checks against the team's positions now; each problem said, and False
    unless --force (then they are warnings)."""
    positions = {
        uav: (state.telemetry.gps.lat, state.telemetry.gps.lon)
        for uav, state in query_states(bus, options.key_space, options.query_timeout).items()
        if uav in team and state.telemetry is not None and state.telemetry.gps is not None
    }
    problems = target_set_problems(options.targets, positions, options.max_reach_km * 1000.0)
    severity = "warning" if options.force else "error"
    for problem in problems:
        print(f"{severity}: {options.file}: {problem}", file=sys.stderr)
    if problems and not options.force:
        print("error: nothing sent (--force sends it all the same)", file=sys.stderr)
        return False
    return True


def _report_delivery(
    bus: Bus, space: KeySpace, message: MissionTargets, timeout_s: float, out: TextIO
) -> None:
    """Without --wait: say which team UAVs have not acknowledged the mission yet;
    MissionCollision if one holds other targets under its id."""
    seen = wait_acknowledged(bus, space, message, timeout_s)
    if (collision := seen.collision(message)) is not None:
        raise collision
    missing = [uav for uav in message.team if uav not in seen.got]
    if missing:
        print(
            f"mission {message.mission}: not yet acknowledged by {', '.join(map(str, missing))}",
            file=out,
        )


def _read_phases(
    bus: Bus,
    space: KeySpace,
    outcome: MissionOutcome,
    follower: MissionFollower,
    timeout_s: float,
) -> None:
    """Each team UAV's phase (and reason) as its own state query answers it; a team UAV
    on a later mission means this one was superseded."""
    for uav, state in query_states(bus, space, timeout_s).items():
        if uav in outcome.team:
            outcome.note_state(state)
            if state.mission is not None:
                follower.note_later_mission(state.mission.mission)
    outcome.superseded_by = follower.superseded_by


SEND_TARGETS = Command(send_options, run_send_targets)
