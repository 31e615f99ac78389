"""The operator's commands from the page, and the mission the page follows.

A command arrives as one JSON object on the WebSocket, tagged by `cmd`:

    {"cmd": "send", "id": 1, "team": [74, 112], "targets": [{"lat":..,"lon":..,"alt":..}]}
    {"cmd": "abort", "id": 2}                 (the mission the page follows, else the latest)
    {"cmd": "opm", "id": 3, "uav": 74, "enabled": false}
    {"cmd": "add-targets", "id": 4, "targets": [...]}   (to the followed mission, or `mission`)
    {"cmd": "remove-targets", "id": 5, "indexes": [2]}

Each gets one reply `{"type": "reply", "id", "ok", "message", "mission"}` when done; a
page's (a string id) is also acknowledged as soon as it is read (`{"type": "ack", "id"}`).
The page's ids are unique to the page and the press, so a command it sends again after
a reconnect is answered, not done twice (`ground.gui.ledger`). A malformed command is
refused with the reason and nothing is sent. Sending reuses the mission manager's own
code (`ground.mission_control`): the same mission ids, the same MissionTargets, the
same follower, the same targets queryable as `ground-cli send-targets`. Adding and
removing targets in flight is `ground-cli add-targets`/`remove-targets`'s own
`change_mission`: answered ok only once every live team UAV planned the new revision,
else failed with who did not. The calls here
block on Zenoh queries: the server runs them off the event loop (`asyncio.to_thread`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Annotated, Any

import msgspec

from fleet.consensus.deadline import MAX_DEADLINE_S, consensus_deadline
from fleet.errors import CodecError
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    MAX_TEAM,
    MAX_ZONES,
    MISSION_MANAGER,
    AssignmentReport,
    MissionTargets,
    NoFlyZone,
    PlanProposal,
    Target,
    TargetIndex,
)
from fleet.mission.no_fly import mission_zone_problem
from fleet.mission.objective import Objective
from fleet.mission.targets_file import TargetsFileError, encode_targets
from fleet.piccolo.stream_packet import MAX_PICCOLO_ID, MIN_PICCOLO_ID
from fleet.transport.bus import Bus
from ground.mission_change_command import ACK_WAIT_S, ChangePut, ChangeRefused, put_change
from ground.mission_control import MissionError, publish_targets, send_abort, send_opm
from ground.mission_follower import MissionFollower
from ground.mission_ids import MAX_MISSION_ID, TargetsServer, claim_mission, current_mission_id
from ground.mission_outcome import MissionOutcome
from ground.proposals_heard import HeardProposal, declined, heard_proposals, team_plans
from ground.propose import (
    ProposalAttempt,
    named_proposers,
    proposal_window,
    propose_when_results,
)

log = logging.getLogger(__name__)

PiccoloId = Annotated[int, msgspec.Meta(ge=MIN_PICCOLO_ID, le=MAX_PICCOLO_ID)]
MissionId = Annotated[int, msgspec.Meta(ge=0, le=MAX_MISSION_ID)]
AckWait = Annotated[float, msgspec.Meta(gt=0, le=120)]
#: A page's id: unique to the page and the press; an integer: a script's, never remembered.
CommandId = int | Annotated[str, msgspec.Meta(min_length=1, max_length=64)]


class SendCommand(msgspec.Struct, frozen=True, tag="send", tag_field="cmd"):
    """Send targets; `deadline_s` None: the one that follows the team (consensus_deadline)."""

    id: CommandId
    team: tuple[PiccoloId, ...]
    targets: tuple[Target, ...]
    deadline_s: Annotated[float, msgspec.Meta(gt=0, le=MAX_DEADLINE_S)] | None = None
    zones: Annotated[tuple[NoFlyZone, ...], msgspec.Meta(max_length=MAX_ZONES)] = ()
    objective: Objective = Objective.GREEDY
    #: The ground proposes a plan solved by its routing solver (`send-targets --propose`).
    propose: bool = False
    #: UAVs that propose a plan, each solved on board (`send-targets --proposers`).
    proposers: Annotated[tuple[PiccoloId, ...], msgspec.Meta(max_length=MAX_TEAM)] = ()


class AbortCommand(msgspec.Struct, frozen=True, tag="abort", tag_field="cmd"):
    id: CommandId
    mission: MissionId | None = None
    uav: PiccoloId | None = None  #: one UAV alone; None: the whole team


class OpmRequest(msgspec.Struct, frozen=True, tag="opm", tag_field="cmd"):
    id: CommandId
    uav: PiccoloId
    enabled: bool
    status_rate_hz: Annotated[float, msgspec.Meta(ge=0, le=100)] = 1.0


class AddTargetsCommand(msgspec.Struct, frozen=True, tag="add-targets", tag_field="cmd"):
    """Add targets to a mission in flight (None: the mission the page follows)."""

    id: CommandId
    targets: Annotated[tuple[Target, ...], msgspec.Meta(min_length=1)]
    mission: MissionId | None = None
    wait_s: AckWait = ACK_WAIT_S  #: how long every live team UAV has to acknowledge it


class RemoveTargetsCommand(msgspec.Struct, frozen=True, tag="remove-targets", tag_field="cmd"):
    """Remove targets (by index) from a mission in flight (None: the one followed)."""

    id: CommandId
    indexes: Annotated[tuple[TargetIndex, ...], msgspec.Meta(min_length=1)]
    mission: MissionId | None = None
    wait_s: AckWait = ACK_WAIT_S


Command = SendCommand | AbortCommand | OpmRequest | AddTargetsCommand | RemoveTargetsCommand
_decoder: msgspec.json.Decoder[Command] = msgspec.json.Decoder(Command)


class CommandError(CodecError):
    """A command from the page that is not one; nothing was sent."""


def decode_command(data: str | bytes) -> Command:
    try:
        return _decoder.decode(data)
    except msgspec.DecodeError as error:
        raise CommandError(f"malformed command ({error}); nothing sent") from None


class ProposalState(StrEnum):
    WAITING = "waiting for the team's results"
    PROPOSED = "proposed by the ground"
    NOT_PROPOSED = "not proposed"


@dataclass
class ProposalTrack:
    """The ground's proposal for one mission sent from the page, as it goes."""

    mission: int
    stop: threading.Event = field(default_factory=threading.Event)
    attempt: ProposalAttempt | None = None  #: set once, by the proposing thread

    @property
    def state(self) -> ProposalState:
        if self.attempt is None:
            return ProposalState.WAITING
        if self.attempt.proposal is None:
            return ProposalState.NOT_PROPOSED
        return ProposalState.PROPOSED


@dataclass(frozen=True)
class Reply:
    id: int | str | None
    ok: bool
    message: str
    mission: int | None = None
    aborted: bool = False

    def to_json(self) -> dict[str, Any]:
        return {
            "type": "reply",
            "id": self.id,
            "ok": self.ok,
            "message": self.message,
            "mission": self.mission,
        }


class MissionDesk:
    """The one mission the page follows: the last it sent, or the latest the fleet has.

    While it follows a mission it sent, it serves that mission's targets by query, as
    `send-targets` does, for UAVs that join late. `on_change` is called (on a bus
    thread) whenever a result or an assignment arrives.
    """

    def __init__(self, bus: Bus, space: KeySpace, on_change: Callable[[], None]) -> None:
        self._bus = bus
        self.space = space
        self._on_change = on_change
        self._lock = threading.Lock()
        self._stack = ExitStack()
        self._follower: MissionFollower | None = None
        self._targets: MissionTargets | None = None
        #: The targets server of the mission this page sent (None: another ground's).
        self._server: TargetsServer | None = None
        #: Each UAV's first plan of the followed mission (epoch 0, revision 0): the
        #: decision that adopted the ground's proposal, or not.
        #: Their own lock: a follower's fetch (on any thread, the proposer's too) calls
        #: `_heard`, and `_follow` stops the proposer while it holds `_lock`.
        self._decisions: dict[int, AssignmentReport] = {}
        self._decisions_lock = threading.Lock()
        self._proposal: ProposalTrack | None = None
        #: The followed mission as the page first heard it: the proposals are for it.
        self._first: MissionTargets | None = None
        #: The proposals heard, checked (`heard_proposals`): kept until what they are
        #: judged from changes, so a push does not check them again.
        self._judged: tuple[object, list[HeardProposal]] | None = None

    def _heard(self, mission: int, message: object) -> None:  # a bus thread
        if isinstance(message, AssignmentReport) and not (message.epoch or message.revision):
            with self._decisions_lock:
                if message.mission == mission:
                    self._decisions.setdefault(message.uav, message)
        self._on_change()

    def _follow(self, message: MissionTargets, serve: bool) -> None:
        """Follow `message`'s mission from now on (caller holds the lock)."""
        self._stack.close()
        self._stack = ExitStack()
        with self._decisions_lock:
            self._decisions = {}
        self._proposal = None
        self._server = None
        mission = message.mission
        follower = MissionFollower(
            self._bus,
            self.space,
            mission,
            lambda _, heard: self._heard(mission, heard),
            on_proposal=lambda _: self._on_change(),
        )
        self._follower = self._stack.enter_context(follower)
        if serve:
            self._server = self._stack.enter_context(TargetsServer(self._bus, self.space, message))
        self._targets = self._first = message
        self._judged = None

    def send(
        self,
        team: tuple[int, ...],
        targets: tuple[Target, ...],
        deadline_s: float,
        zones: tuple[NoFlyZone, ...] = (),
        objective: Objective = Objective.GREEDY,
        proposals_s: float = 0.0,
        proposers: tuple[int, ...] = (),
        propose: bool = True,
    ) -> int:
        """Claim a mission id no other ground uses (`claim_mission`), follow it, put it,
        naming `proposers` (`ground.propose.named_proposers`); with `proposals_s` and
        `propose`, propose the ground's plan once the team's results are in
        (`ground.propose`, as `send-targets --propose`), on a thread of its own."""

        def make(mission: int) -> MissionTargets:
            return MissionTargets(
                mission=mission,
                team=team,
                targets=targets,
                deadline_s=deadline_s,
                zones=zones,
                objective=objective,
                proposals_s=proposals_s,
                proposers=proposers,
            )

        with self._lock:
            claim = ExitStack()
            server = claim.enter_context(claim_mission(self._bus, self.space, make, 1.0))
            message = server.targets
            self._follow(message, serve=False)
            self._server = server
            # The claimed id's targets server stays open as long as the mission is followed.
            self._stack.push(claim)
            publish_targets(self._bus, self.space, message)
            if proposals_s > 0 and propose:
                assert self._follower is not None
                track = self._proposal = ProposalTrack(message.mission)
                thread = threading.Thread(
                    target=self._propose,
                    args=(message, self._follower, track),
                    name=f"propose-{message.mission}",
                    daemon=True,
                )
                # Stopped (not joined: the lock is held, and a solve may take seconds; its
                # outcome then goes to a track no longer shown) when the page follows
                # another mission, or closes.
                self._stack.callback(track.stop.set)
                thread.start()
        self._on_change()
        return message.mission

    def _propose(
        self, message: MissionTargets, follower: MissionFollower, track: ProposalTrack
    ) -> None:
        try:
            attempt = propose_when_results(self._bus, self.space, message, follower, track.stop)
        except Exception as error:  # the page must go on; the reason is shown
            if track.stop.is_set():
                return  # the page moved on, or closed (its bus with it)
            log.exception("mission %d: proposing a plan failed", message.mission)
            attempt = ProposalAttempt(None, reason=f"failed: {error}")
        track.attempt = attempt
        self._on_change()

    def _heard_proposals(self) -> tuple[MissionTargets, list[HeardProposal]] | None:
        """Every proposal heard for the followed mission (the ground's from this page as
        it put it), checked as the UAVs check them and judged from their first plans."""
        with self._lock:
            first, follower, track = self._first, self._follower, self._proposal
        if first is None or follower is None:
            return None
        proposals: dict[int, PlanProposal] = follower.proposal_snapshot()
        attempt = track.attempt if track is not None else None
        if attempt is not None and attempt.proposal is not None:
            proposals[MISSION_MANAGER] = attempt.proposal
        results = follower.snapshot()[0]
        with self._decisions_lock:
            decisions = dict(self._decisions)
        inputs = (
            first.mission,
            sorted(proposals.items()),
            sorted(results.items()),
            sorted(decisions.items()),
        )
        judged = self._judged
        if judged is not None and judged[0] == inputs:
            return first, judged[1]
        heard = heard_proposals(first, results, proposals, list(decisions.values()))
        self._judged = (inputs, heard)
        return first, heard

    def proposals_json(self) -> dict[str, Any] | None:
        """Every proposal heard for the followed mission, for the page: by whom, the
        UAVs' checks of it (right, validity, score) run here, and what the UAVs' first
        plans say of it (their reported digests); the named proposers not heard; the
        plans the UAVs committed to, with their scores. None for a mission with no
        proposal window and no proposal heard."""
        judged = self._heard_proposals()
        if judged is None:
            return None
        first, heard = judged
        if not heard and first.proposals_s <= 0.0:
            return None
        with self._decisions_lock:
            decisions = list(self._decisions.values())
        with self._lock:
            follower = self._follower
        results = follower.snapshot()[0] if follower is not None else {}
        proposers = {seen.proposer for seen in heard}
        return {
            "named": list(first.proposers),
            "window_s": first.proposals_s,
            "heard": [seen.to_json() for seen in heard],
            "not_heard": [p for p in first.proposers if p not in proposers],
            "declined": declined(first, results),
            "plans": team_plans(decisions, first.mission),
        }

    def proposal_json(self) -> dict[str, Any] | None:
        """The ground's proposal for the followed mission and what the UAVs' decisions
        say of it (their reported digests), for the page; None without one."""
        with self._lock:
            track = self._proposal
        if track is None:
            return None
        attempt = track.attempt
        data: dict[str, Any] = {
            "mission": track.mission,
            "state": str(track.state),
            "reason": attempt.reason if attempt is not None else None,
            "cpu_s": attempt.cpu_s if attempt is not None else None,
            "verdict": None,
        }
        if attempt is None or attempt.proposal is None:
            return data
        # The same verdict and check as every proposal heard (`proposals_json`).
        judged = self._heard_proposals()
        for seen in judged[1] if judged is not None else ():
            if seen.proposer == attempt.proposal.proposer:
                data.update(seen.to_json())
        return data

    @property
    def mission(self) -> int | None:
        with self._lock:
            return self._targets.mission if self._targets is not None else None

    def adopt(self, mission: int, timeout_s: float) -> bool:
        """Follow `mission` (sent by another ground), if some UAV serves its targets."""
        found = self._bus.query_messages(
            self.space.mission_targets(mission), MissionTargets, timeout_s
        )
        with self._lock:
            if self._targets is not None and self._targets.mission >= mission:
                return False
            for _, message in found:
                if message.mission == mission:
                    self._follow(message, serve=False)
                    break
            else:
                return False
        assert self._follower is not None
        self._follower.fetch(timeout_s)
        self._on_change()
        return True

    def follow_later(self, message: MissionTargets, timeout_s: float) -> bool:
        """Follow `message`'s mission, heard on the bus from another ground, if it is later
        than the one followed (the page follows the latest mission)."""
        with self._lock:
            if self._targets is not None and self._targets.mission >= message.mission:
                return False
            self._follow(message, serve=False)
            follower = self._follower
        assert follower is not None
        follower.fetch(timeout_s)
        self._on_change()
        return True

    def revise(self, message: MissionTargets) -> bool:
        """Take a later revision of the mission followed (changed in flight, by this
        page or any ground): its targets added and removed are shown from now on."""
        with self._lock:
            held = self._targets
            if held is None or message.mission != held.mission:
                return False
            if message.revision <= held.revision:
                return False
            self._targets = message
            if self._server is not None:
                self._server.revise(message)
        self._on_change()
        return True

    def outcome(self) -> MissionOutcome | None:
        with self._lock:
            if self._targets is None or self._follower is None:
                return None
            message, follower = self._targets, self._follower
        outcome = MissionOutcome(
            message.mission, message.team, message.targets, removed=frozenset(message.removed)
        )
        outcome.zones = message.zones
        outcome.results, outcome.assignments = follower.snapshot()
        outcome.outcomes = follower.outcome_snapshot()
        judged = self._heard_proposals()
        for seen in judged[1] if judged is not None else ():
            if seen.proposer == MISSION_MANAGER:
                outcome.proposal = seen
            else:
                outcome.uav_proposals[seen.proposer] = seen
        return outcome

    def close(self) -> None:
        with self._lock:
            self._stack.close()
            self._follower = None


def _send(desk: MissionDesk, command: SendCommand, live: set[int]) -> Reply:
    if not command.team:
        return Reply(command.id, False, "no team: select at least one UAV; nothing sent")
    try:
        encode_targets(command.targets, source="the page's targets")
    except TargetsFileError as error:
        return Reply(command.id, False, f"target {error.index}: {error.problem}; nothing sent")
    problem = mission_zone_problem(command.zones, command.targets)
    if problem is not None:
        return Reply(command.id, False, f"{problem}; nothing sent")
    team = tuple(sorted(set(command.team)))
    try:
        proposers = named_proposers(command.propose, command.proposers, team)
        deadline_s = command.deadline_s or consensus_deadline(len(team))
        proposals_s = 0.0
        if command.propose or command.proposers:
            deadline_s, proposals_s = proposal_window(command.objective, deadline_s)
        mission = desk.send(
            team,
            command.targets,
            deadline_s,
            command.zones,
            command.objective,
            proposals_s,
            proposers=proposers,
            propose=command.propose,
        )
    except (MissionError, ValueError) as error:
        return Reply(command.id, False, f"{error}; nothing sent")
    absent = [uav for uav in team if uav not in live]
    note = f" (not live now: {', '.join(map(str, absent))})" if absent else ""
    return Reply(
        command.id,
        True,
        f"mission {mission}: {len(command.targets)} targets"
        + (f" and {len(command.zones)} no-fly zones" if command.zones else "")
        + " published to "
        f"{', '.join(map(str, team))}{note}; waiting for their results"
        + ("; the ground proposes a plan once they are in" if command.propose else "")
        + (
            f"; UAV {', '.join(map(str, command.proposers))} to propose a plan"
            if command.proposers
            else ""
        ),
        mission=mission,
    )


def _abort(bus: Bus, desk: MissionDesk, command: AbortCommand) -> Reply:
    mission = command.mission
    if mission is None:
        mission = desk.mission
    if mission is None:
        mission = current_mission_id(bus, desk.space, 1.0)
    if mission is None:
        return Reply(command.id, False, "no mission to abort (none seen)")
    send_abort(bus, desk.space, mission, command.uav)
    if command.uav is not None:
        return Reply(command.id, True, f"mission {mission}: abort sent to UAV {command.uav}")
    return Reply(
        command.id, True, f"mission {mission}: abort sent to the team", mission, aborted=True
    )


ChangeCommand = AddTargetsCommand | RemoveTargetsCommand


def put_change_of(bus: Bus, desk: MissionDesk, command: ChangeCommand) -> Reply | ChangePut:
    """`add-targets` / `remove-targets` as the CLI makes them, in the command's turn: the
    change put (and shown at once), or the reply refusing it, nothing sent."""
    added = command.targets if isinstance(command, AddTargetsCommand) else ()
    removed = command.indexes if isinstance(command, RemoveTargetsCommand) else ()
    mission = command.mission if command.mission is not None else desk.mission
    try:
        put = put_change(bus, desk.space, mission, added=added, removed=removed)
    except ChangeRefused as error:
        return Reply(command.id, False, str(error), mission)
    # Shown at once, and served as it is now, not only once the page hears it.
    desk.revise(put.new)
    return put


def change_reply(
    command: ChangeCommand, put: ChangePut, stop: threading.Event | None = None
) -> Reply:
    """A change put, once every live team UAV planned its revision: ok; else failed,
    naming who did not within the command's `wait_s`."""
    with put:
        change = put.wait(command.wait_s, stop)
    return Reply(command.id, change.acknowledged, change.summary(), change.new.mission)


def execute(bus: Bus, desk: MissionDesk, command: Command, live: set[int]) -> Reply:
    """Carry out one command (blocking); the reply says what was done, or why not."""
    if isinstance(command, SendCommand):
        return _send(desk, command, live)
    if isinstance(command, AddTargetsCommand | RemoveTargetsCommand):
        put = put_change_of(bus, desk, command)
        return put if isinstance(put, Reply) else change_reply(command, put)
    if isinstance(command, AbortCommand):
        return _abort(bus, desk, command)
    if command.uav not in live:
        return Reply(command.id, False, f"UAV {command.uav} is not live; nothing sent")
    send_opm(bus, desk.space, command.uav, command.enabled, command.status_rate_hz)
    state = "on" if command.enabled else "off"
    return Reply(
        command.id,
        True,
        f"UAV {command.uav}: planning module {state} sent; its status message confirms it",
    )
