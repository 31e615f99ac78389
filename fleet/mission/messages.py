"""Typed planning-level messages, shared by the binary planning protocol and Zenoh.

One struct per application message. The binary onboard planning protocol
(`fleet.payload.protocol`) encodes these to the payload stream; the Zenoh layer
publishes the very same structs as JSON. A command therefore has one type whichever
path it travelled.
"""

from __future__ import annotations

from typing import Annotated

import msgspec
from msgspec import Meta

from fleet.mission.objective import Objective
from fleet.mission.phase import Phase, Severity
from fleet.mission.status_kind import StatusKind
from fleet.piccolo.telemetry import Telemetry

#: Planning-protocol address of every UAV (thesis 2.9).
BROADCAST = 0xFFFF
#: Planning-protocol address of the Mission Manager (thesis 2.9).
MISSION_MANAGER = 0xFFFE

#: Targets in one mission at most (fleet.mission.targets_file refuses a longer file).
MAX_TARGETS = 100
#: UAVs in one team at most.
MAX_TEAM = 256

# Bounds every message carries into its JSON Schema and msgspec enforces on decode, so
# an out-of-range id or index from the bus is refused, never used as an index.
#: Mission ids are u32 on the planning protocol.
MissionId = Annotated[int, Meta(ge=0, le=0xFFFF_FFFF)]
#: A Piccolo ID (fleet.piccolo.stream_packet: 0x0001-0xFFF0).
PiccoloId = Annotated[int, Meta(ge=0x0001, le=0xFFF0)]
#: A target's index in its mission.
TargetIndex = Annotated[int, Meta(ge=0, le=MAX_TARGETS - 1)]
Team = Annotated[tuple[PiccoloId, ...], Meta(max_length=MAX_TEAM)]
#: How many times one UAV left a mission, or came back (fleet.consensus.membership).
MembershipCount = Annotated[int, Meta(ge=0, le=0xFFFF)]
#: An epoch is the sum of every team UAV's three counts (left, back, asked) and the
#: mission's revision.
MAX_EPOCH = 3 * MAX_TEAM * 0xFFFF + 0xFFFF
#: One UAV's ordered targets.
Queue = Annotated[tuple[TargetIndex, ...], Meta(max_length=MAX_TARGETS)]
Arrivals = Annotated[tuple[float, ...], Meta(max_length=MAX_TARGETS)]


class Target(msgspec.Struct, frozen=True):
    """One target: degrees and metres (altitude travels as f32 on the payload link)."""

    lat: float
    lon: float
    alt: float


#: No-fly zones in one mission at most.
MAX_ZONES = 16
#: Vertices of one zone at most (fleet.geo.zones.MAX_ZONE_VERTICES), closing one included.
MAX_ZONE_RING = 65
Latitude = Annotated[float, Meta(ge=-90.0, le=90.0)]
Longitude = Annotated[float, Meta(ge=-180.0, le=180.0)]


class NoFlyZone(msgspec.Struct, frozen=True):
    """A polygon no aircraft may enter: its ring of (latitude, longitude) degrees.

    The ring's shape (closed, not self-intersecting, at least three vertices) is checked
    by `fleet.mission.no_fly`, on the ground before sending and on every UAV on receipt.
    """

    ring: Annotated[tuple[tuple[Latitude, Longitude], ...], Meta(max_length=MAX_ZONE_RING)]
    name: Annotated[str, Meta(max_length=64)] = ""


class OpmCommand(msgspec.Struct, frozen=True):
    """PAYLOAD_OPM: the ground turns the onboard planning module on or off.

    `status_rate_hz` is how often the module sends a status message; 0 means only on
    change.
    """

    enabled: bool
    status_rate_hz: float = 1.0


class StatusText(msgspec.Struct, frozen=True):
    """PAYLOAD_STATUS: a status message from a UAV to the Mission Manager.

    `kind` says what happened; `mission` and `target` are the mission and the target
    index it concerns, when it concerns one. Receivers act on these, never on `text`,
    which is for people. `severity` is on the wire for tools that read the JSON alone;
    it is always `kind.severity` (set here, whatever a sender passes).

    The binary payload link carries the text alone: its edge gives it a generic kind
    (`fleet.payload.bodies.decode_status`). A message recorded before kinds existed
    decodes as `INFO`; `fleet.recording.mission_log` reads such records by their text.
    """

    text: str
    kind: StatusKind = StatusKind.INFO
    mission: MissionId | None = None
    target: TargetIndex | None = None
    severity: Severity = Severity.INFO

    def __post_init__(self) -> None:
        msgspec.structs.force_setattr(self, "severity", self.kind.severity)


class MissionTargets(msgspec.Struct, frozen=True):
    """PAYLOAD_TARGETS: a mission's team (Piccolo IDs) and its targets.

    `mission` is a u32 mission id; a higher id supersedes a lower one.
    `deadline_s` is how long after receipt a UAV waits for its teammates' results.
    `zones` are the no-fly zones every route keeps out of (fleet.mission.no_fly); the
    binary payload link has no room for them (fleet.payload.bodies refuses to send a
    mission that has some).
    `objective` is what the plan optimises (fleet.consensus.objectives); a mission sent
    before objectives existed, or over the binary payload link, is `greedy`.
    `proposals_s`: how long (s after receipt) a UAV holding every teammate's result
    waits for a proposed plan (`PlanProposal`) before it decides on the baseline alone;
    0, none is expected (fleet.consensus.proposal).
    """

    mission: MissionId
    team: Team
    targets: Annotated[tuple[Target, ...], Meta(max_length=MAX_TARGETS)]
    deadline_s: float = 10.0
    zones: Annotated[tuple[NoFlyZone, ...], Meta(max_length=MAX_ZONES)] = ()
    objective: Objective = Objective.GREEDY
    proposals_s: Annotated[float, Meta(ge=0.0, le=3600.0)] = 0.0
    #: The mission changed in flight (fleet.consensus.mission_change): 0 as first sent;
    #: each change puts the whole mission again, one revision higher, its added targets
    #: after the others (an index never changes) and `removed` holding every target
    #: taken off, never flown from then on.
    revision: Annotated[int, Meta(ge=0, le=0xFFFF)] = 0
    removed: Annotated[tuple[TargetIndex, ...], Meta(max_length=MAX_TARGETS)] = ()
    #: How many of `targets` the mission had as first sent (what the UAVs' results time);
    #: None: all of them.
    planned: Annotated[int, Meta(ge=1, le=MAX_TARGETS)] | None = None
    #: Who may propose a plan within `proposals_s` (Piccolo IDs; the ground's is
    #: MISSION_MANAGER): a UAV started with `--propose` proposes when it is named (and in
    #: the team), and the UAVs wait (within the window) for a valid proposal from each
    #: one named. Empty: the ground alone, its first valid proposal ending the wait. Any
    #: other proposer's plan is refused (fleet.consensus.proposal.right_problem).
    proposers: Annotated[
        tuple[Annotated[int, Meta(ge=1, le=0xFFFF)], ...], Meta(max_length=MAX_TEAM)
    ] = ()


class UavResult(msgspec.Struct, frozen=True):
    """PAYLOAD_UAVRESULT: one UAV's approach time (s) to each target of a mission.

    `times[i]` is the time to `targets[i]`; None where the UAV has no answer.
    `model_times` and `fallback_times` say how many of the times came from the approach
    model and how many from the Dubins fallback (optional: None from a UAV that does not
    say, and over the payload link, whose binary message has no room for them).
    `airspeed` (m/s), `wind_east` and `wind_north` (m/s, the smoothed wind the times
    were planned in, the way it blows to) and `lat`, `lon` (where the UAV planned from)
    time the legs of its queue (fleet.consensus.legs, docs/queues.md); None from a UAV
    that does not say (the legs are then in still air at 22 m/s). Digested with the
    times: every UAV plans the same legs.
    """

    mission: MissionId
    uav: PiccoloId
    times: Annotated[tuple[float | None, ...], Meta(max_length=MAX_TARGETS)]
    model_times: Annotated[int, Meta(ge=0)] | None = None
    fallback_times: Annotated[int, Meta(ge=0)] | None = None
    airspeed: Annotated[float, Meta(gt=0.0, le=200.0)] | None = None
    wind_east: Annotated[float, Meta(ge=-200.0, le=200.0)] | None = None
    wind_north: Annotated[float, Meta(ge=-200.0, le=200.0)] | None = None
    lat: Latitude | None = None
    lon: Longitude | None = None
    #: A *standing* for a re-plan epoch (fleet.consensus.resolve), not the mission's
    #: first result: the digest of the epoch's append plan it answers. Its times are then
    #: from where the UAV is now (`lat`, `lon`) to every target of the mission's current
    #: revision. None: the mission's first result.
    basis: Annotated[str, Meta(max_length=64)] | None = None
    #: With `basis`: the target this UAV is flying now, None if none.
    flying: TargetIndex | None = None
    #: With `basis`: the targets this UAV reached itself, ascending (its word is believed
    #: of itself only: a target it says another UAV reached is planned again, and
    #: skipped by its holder if that UAV's own outcome says it reached it).
    reached: Annotated[tuple[TargetIndex, ...], Meta(max_length=MAX_TARGETS)] = ()
    #: With `basis`: how many re-plans in changed air this UAV asked for so far (its own
    #: count, fleet.consensus.membership): a teammate that counts fewer takes it, and
    #: re-plans that epoch too (onboard.air_watch).
    asked: MembershipCount = 0
    #: Whether this UAV will propose a plan for the mission (started with `--propose`,
    #: its solver importable, named among the mission's proposers, a window and an
    #: objective to propose for). Digested with the times: every UAV holding the same
    #: results waits for the same proposers, and none for a named UAV that says False
    #: (fleet.consensus.proposal.awaited_proposers). None: it does not say (an older
    #: UAV, a standing, the payload link): it may propose.
    proposes: bool | None = None


class MissionAbort(msgspec.Struct, frozen=True):
    """PAYLOAD_ABORT: the ground aborts a mission; every UAV resumes its course.

    `uav` names one UAV to abort alone (its teammates fly on); None aborts the whole
    team. The binary payload link carries the mission id only, so an abort sent that
    way is always the team's.
    """

    mission: MissionId
    uav: PiccoloId | None = None


class LinkHealth(msgspec.Struct, frozen=True):
    """The serial link as the onboard adapter sees it."""

    program_up: bool
    payload_up: bool
    packets: int
    drops: dict[str, int]
    telemetry_age_s: float | None  #: seconds since the last telemetry; None before any


class CommandResult(msgspec.Struct, frozen=True):
    """Answer to a waypoint or track command: confirmed by the autopilot's echo, or not."""

    ok: bool
    detail: str
    attempts: int = 0


class AssignmentReport(msgspec.Struct, frozen=True):
    """A UAV's committed outcome of a mission's consensus.

    `digest` identifies the exact set of results the greedy was fed; every UAV that
    used the same results reports the same digest and the same `pairs`.
    """

    mission: MissionId
    uav: PiccoloId
    target: TargetIndex | None  #: index of this UAV's target in the mission, None if idle
    #: every UAV's target index, keyed by Piccolo ID (a string in JSON: `{"74": 0}`)
    pairs: Annotated[dict[PiccoloId, TargetIndex], Meta(max_length=MAX_TEAM)]
    unassigned: Annotated[tuple[TargetIndex, ...], Meta(max_length=MAX_TARGETS)]
    team: Team  #: the UAVs whose results were used
    digest: str
    eta_s: float | None = None
    #: 0 for the consensus; after a re-plan (fleet.consensus.replan), the sum of the
    #: membership counts (`left`, `back`): the number of team UAVs released, listed in
    #: `released`, while none came back.
    epoch: Annotated[int, Meta(ge=0, le=MAX_EPOCH)] = 0
    released: Team = ()
    #: Each UAV's ordered queue of targets (fleet.consensus.queues), keyed by Piccolo ID;
    #: `pairs` holds each queue's first. Empty from a UAV that does not say.
    queues: Annotated[dict[PiccoloId, Queue], Meta(max_length=MAX_TEAM)] = {}
    #: The predicted arrival (s after the results were computed) at each queued target,
    #: in queue order.
    arrivals: Annotated[dict[PiccoloId, Arrivals], Meta(max_length=MAX_TEAM)] = {}
    objective: Objective = Objective.GREEDY
    #: Why each target in `unassigned` is served by none.
    unserved: Annotated[dict[TargetIndex, str], Meta(max_length=MAX_TARGETS)] = {}
    #: How many times each UAV was counted out of the mission, and back in
    #: (fleet.consensus.membership); empty while nobody came back.
    left: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}
    back: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}
    #: The mission's revision this plan is of (MissionTargets.revision).
    revision: Annotated[int, Meta(ge=0, le=0xFFFF)] = 0
    #: A re-plan solved again from the survivors' standings (fleet.consensus.resolve):
    #: the digest of the epoch's append plan it replaces. None: not resolved.
    basis: Annotated[str, Meta(max_length=64)] | None = None
    #: How many re-plans in changed air each UAV asked for (fleet.consensus.membership);
    #: empty while none did. Counted in the epoch.
    asked: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}


class PlanProposal(msgspec.Struct, frozen=True):
    """A plan proposed for a mission by any party (the ground, with a routing solver):
    every UAV re-scores it with the deterministic scorer and adopts the best of the
    baseline and the valid proposals (fleet.consensus.proposal).

    `proposer` is the proposer's Piccolo ID (the ground's is MISSION_MANAGER); `digest`
    the results digest of the inputs it was solved from (a UAV that holds other results
    ignores it); `queues` every UAV's ordered queue.
    """

    mission: MissionId
    proposer: Annotated[int, Meta(ge=1, le=0xFFFF)]
    digest: Annotated[str, Meta(max_length=64)]
    objective: Objective
    queues: Annotated[dict[PiccoloId, Queue], Meta(max_length=MAX_TEAM)]


class AssignmentHeader(msgspec.Struct, frozen=True):
    """The fields of an `AssignmentReport` that decide whether it changes anything for a
    UAV that has committed (`fleet.consensus.mission_round.Settled`): decoded alone, the
    rest of the report (its pairs, team and digest) is skipped, not validated.

    At each re-plan epoch every onboard hears its N-2 surviving teammates' re-plans
    (`fleet/mission/{m}/replan/{id}`), nearly all of which change nothing for a UAV
    that re-planned the same epoch; the ground decodes and checks every report in full.
    """

    mission: MissionId
    uav: PiccoloId
    epoch: Annotated[int, Meta(ge=0, le=MAX_EPOCH)] = 0
    released: Team = ()
    left: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}
    back: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}
    #: The mission's revision this plan is of (MissionTargets.revision).
    revision: Annotated[int, Meta(ge=0, le=0xFFFF)] = 0
    #: A resolved re-plan: the digest of the append plan it replaces.
    basis: Annotated[str, Meta(max_length=64)] | None = None
    #: The epoch-0 team the plan is built on: two plans of one mission after a heal
    #: (fleet.consensus.heal).
    team: Team = ()
    #: Re-plans in changed air asked for, by UAV (fleet.consensus.membership).
    asked: Annotated[dict[PiccoloId, MembershipCount], Meta(max_length=MAX_TEAM)] = {}


class TargetOutcome(msgspec.Struct, frozen=True):
    """How a UAV's part in a mission ended, or why it dropped out of it.

    `phase` is `reached` (telemetry put it inside the acceptance radius of `target`),
    `failed` (it cannot fly `target`: `reason`) or `link_lost` (its autopilot went
    silent). A UAV that published `failed` or `link_lost` is released from the mission:
    its teammates re-plan its target (fleet.consensus.replan).
    """

    mission: MissionId
    uav: PiccoloId
    target: TargetIndex | None
    phase: Phase
    reason: str | None = None
    #: Every target of the mission this UAV knows reached, and by which UAV (its own
    #: outcomes and its teammates'), so that the latest outcome of any UAV tells a ground
    #: that joins late what a lost UAV had reached.
    reached: Annotated[dict[TargetIndex, PiccoloId], Meta(max_length=MAX_TARGETS)] = {}


class MissionProgress(msgspec.Struct, frozen=True):
    """Where a UAV stands in its current mission (part of UavState)."""

    mission: MissionId
    phase: Phase
    targets: Annotated[int, Meta(ge=0, le=MAX_TARGETS)]
    result: UavResult | None = None
    assignment: AssignmentReport | None = None
    #: The turns (latitude, longitude) of the route it flies to its target around the
    #: mission's no-fly zones; empty for the straight line (onboard.route_flight).
    route: Annotated[tuple[tuple[Latitude, Longitude], ...], Meta(max_length=MAX_ZONE_RING)] = ()
    #: The digest of the MissionTargets it holds (`fleet.consensus.targets_digest`): the
    #: ground checks it is the mission it sent, not another under the same id. None from
    #: a UAV that does not say (the id alone is then believed).
    targets_digest: Annotated[str, Meta(max_length=64)] | None = None
    #: The target it flies to now or last flew to: along a task queue, not always the
    #: first of its queue (its `assignment.target`). None from a UAV that does not say.
    current_target: TargetIndex | None = None
    #: The mission's targets it knows reached, and by whom (its own and its teammates').
    reached: Annotated[dict[TargetIndex, PiccoloId], Meta(max_length=MAX_TARGETS)] = {}
    #: Its time (s) for the leg to `current_target`, timed when it began that leg, in
    #: the air it flew in then (its smoothed airspeed and wind, from where it was): a
    #: plan's leg times are in the air at the plan, which the wind leaves as it drifts
    #: (docs/queues.md). For a queue's first target, its result's approach time. None
    #: from a UAV that does not say, or could not time it.
    leg_s: Annotated[float, Meta(ge=0.0)] | None = None


class UavState(msgspec.Struct, frozen=True):
    """A UAV's answer to a state query: all a ground station needs at a glance."""

    uav: int
    enabled: bool
    status_rate_hz: float
    tracked_waypoint: int | None
    telemetry: Telemetry | None  #: the latest telemetry
    link: LinkHealth | None
    mission: MissionProgress | None
    last_status: str | None = None
    #: The UAV's phase as a whole: `off` and `link_lost` override the mission's phase.
    phase: Phase = Phase.IDLE
    reason: str | None = None  #: why, for preempted, failed, link_lost and a declined mission
    #: The approach model's top speed (m/s) once it is built; None before (it is built
    #: on the first GPS telemetry, at the cruise speed) or from a UAV that does not say.
    model_speed: float | None = None


#: Kinds of refused link a router counts (fleet.transport.link_refusal) at most.
MAX_REFUSAL_KINDS = 16
RefusalCount = Annotated[int, Meta(ge=0)]


class RouterState(msgspec.Struct, frozen=True):
    """A secure router's answer to a state query (`ground-cli routers`): the links it
    refused since it started, by kind (`no_certificate`, `unknown_ca`, ...; none: {})."""

    zid: str
    refused_links: Annotated[dict[str, RefusalCount], Meta(max_length=MAX_REFUSAL_KINDS)]
    #: The query's payload it answers (the ground's random challenge): a signed answer
    #: to an earlier query cannot be replayed for a later one. None: none was asked.
    challenge: Annotated[str, Meta(max_length=64)] | None = None


#: Identities a roster may name (a ground, routers, and two per UAV: well above any fleet).
MAX_IDENTITIES = 4096
IdentityName = Annotated[str, Meta(min_length=1, max_length=64)]


class RosterDocument(msgspec.Struct, frozen=True):
    """The fleet's roster of signers as `fleet certs` writes it (`signers.json`): each
    identity's public signing key (hex), the identities withdrawn, and the CA's signature
    over both. Put on `roster` when an identity is revoked: every running process checks
    the CA's signature and refuses the revoked identities from then on."""

    signers: Annotated[
        dict[IdentityName, Annotated[str, Meta(max_length=64)]], Meta(max_length=MAX_IDENTITIES)
    ]
    revoked: Annotated[list[IdentityName], Meta(max_length=MAX_IDENTITIES)]
    signature: Annotated[str, Meta(max_length=512)]


#: Samples one digest may vouch for: half a second of a UAV's streams is a few dozen.
MAX_DIGEST_SAMPLES = 1024


class StreamDigest(msgspec.Struct, frozen=True):
    """What a UAV put on its unsigned streams (telemetry, track, waypoint echoes, status,
    link health) since its last digest: the hash of each sample (key and payload,
    `fleet.transport.stream_auth`), hex. Signed by the UAV: a receiver believes a stream
    sample once a digest of its author lists it, so one signature covers many samples."""

    uav: PiccoloId
    hashes: Annotated[
        list[Annotated[str, Meta(min_length=32, max_length=32)]],
        Meta(max_length=MAX_DIGEST_SAMPLES),
    ]
