"""Every Zenoh key of the fleet, declared once: what it carries and how it is treated.

Each key is a `KeySpec`: its pattern below the key prefix (`uav/{id}/telemetry`,
`mission/{m}/assignment/{id}`; `{id}` is a Piccolo ID, `{m}` a mission id, `{index}` a
waypoint index, all in decimal), the message struct it carries, how urgently it
travels, whether it commands the fleet or tells its state, who may write and serve it,
and how a recording keeps it. Everything else that describes keys is derived from
`REGISTRY`: concrete keys and wildcards (`fleet.mission.key_space.KeySpace`), the JSON
Schemas (`fleet.mission.schemas`), the QoS (`fleet.transport.bus_qos`), the key check
(`fleet.mission.key_check`), the access policy (`fleet.mission.access`) and the
recording channels (`fleet.recording.channels`).

Layout (under the prefix, `fleet` by default):

    uav/{id}/alive               liveliness token: the UAV process is up
    uav/{id}/telemetry           Telemetry (latest TELEMETRY_HI_RES)
    uav/{id}/track               Track (the waypoint the autopilot tracks)
    uav/{id}/waypoint/{index}    Waypoint (as echoed by the autopilot)
    uav/{id}/status              StatusText (thesis PAYLOAD_STATUS)
    uav/{id}/link                LinkHealth
    uav/{id}/state               UavState, put at the OPM status rate and served
    uav/{id}/digest              StreamDigest: the hashes of the UAV's stream samples
                                 (telemetry ... link) since its last, signed
    uav/{id}/opm                 OpmCommand, ground -> UAV
    uav/{id}/cmd/waypoint        queryable: Waypoint in, CommandResult out
    uav/{id}/cmd/track           queryable: Track in, CommandResult out
    mission/{m}/targets          MissionTargets, ground -> team (served too)
    mission/{m}/result/{id}      UavResult (served too: late fetch; a standing relayed)
    mission/{m}/assignment/{id}  AssignmentReport (republished at each re-plan epoch)
    mission/{m}/replan/{id}      AssignmentReport of a re-plan (epoch > 0) only: what
                                 teammates subscribe to (docs/lifecycle.md)
    mission/{m}/outcome/{id}     TargetOutcome: reached, failed or link_lost
    mission/{m}/abort            MissionAbort, ground -> team (served too)
    mission/{m}/proposal         PlanProposal, ground -> team: a plan to verify
    mission/{m}/proposal/{id}    PlanProposal, UAV id -> team: its own plan to verify
    router/state                 queryable: RouterState, served by each secure router
    roster                       RosterDocument, ground -> all: the CA-signed roster of
                                 signers, put when an identity is revoked
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, Flag, auto

import msgspec

from fleet.mission import messages
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint

#: The key prefix when none is chosen; also the one the schemas show their keys under.
DEFAULT_PREFIX = "fleet"

#: The placeholders a pattern may hold: a Piccolo ID, a mission id, a waypoint index.
UAV_ID = "id"
MISSION_ID = "m"
INDEX = "index"
PLACEHOLDERS = (UAV_ID, MISSION_ID, INDEX)


class Role(Enum):
    """What a key's messages are to the fleet."""

    COMMAND = auto()  #: tells the fleet to act: recorded, never replayed
    STATE = auto()  #: tells what is: replayed as it was recorded


class Urgency(Enum):
    """How a put on the key travels (fleet.transport.bus_qos maps it to Zenoh's QoS)."""

    URGENT = auto()  #: mission traffic and commands: a queue of their own, never dropped
    TELEMETRY = auto()  #: least urgent, dropped under congestion: the next one follows
    ORDINARY = auto()  #: Zenoh's defaults


class Carriage(Flag):
    """How the key travels on Zenoh."""

    PUT = auto()  #: published: subscribers hear it
    QUERY = auto()  #: a queryable answers queries on it
    TOKEN = auto()  #: a liveliness token, neither put nor served


class Party(Enum):
    """Who may write or serve a key (fleet.mission.access)."""

    GROUND = auto()
    OWN_UAV = auto()  #: the UAV whose Piccolo ID is in the key
    ANY_UAV = auto()  #: any UAV of the fleet
    ROUTER = auto()  #: a router of the fleet, for itself


class Recording(Enum):
    """How a recording keeps the key (fleet.recording.channels)."""

    MESSAGE = auto()  #: a channel per key, with its message's JSON Schema
    LIVELINESS = auto()  #: a channel of the token appearing (true) or going (false)
    UNHEARD = auto()  #: query-only: a subscriber never hears it, so it is never recorded


@dataclass(frozen=True)
class KeySpec:
    """One key of the fleet; the defaults are the common case, a UAV publishing its state."""

    pattern: str  #: below the prefix, with {id}, {m} and {index} placeholders
    message: type[msgspec.Struct] | None  #: put on the key, or a query's payload; None: token
    role: Role = Role.STATE
    carriage: Carriage = Carriage.PUT
    writer: Party = Party.OWN_UAV  #: puts it, declares its token, or asks (a query-only key)
    recording: Recording = Recording.MESSAGE
    urgency: Urgency = Urgency.ORDINARY
    reply: type[msgspec.Struct] | None = None  #: what a query's answer carries
    servers: frozenset[Party] = frozenset()  #: declare a queryable on it and reply
    uavs_fetch: bool = False  #: any UAV may query it (the ground may query every key)
    note: str = ""  #: shown beside the key in its message's JSON Schema

    @property
    def chunks(self) -> tuple[str, ...]:
        return tuple(self.pattern.split("/"))

    @property
    def placeholders(self) -> tuple[str, ...]:
        return tuple(c[1:-1] for c in self.chunks if c.startswith("{"))

    @property
    def tree(self) -> str:
        """The first chunk: `uav`, `mission` or `router`."""
        return self.chunks[0]

    @property
    def leaf(self) -> str:
        """The last fixed chunk: `telemetry`, `waypoint`, `assignment`, ..."""
        return next(c for c in reversed(self.chunks) if not c.startswith("{"))

    def fill(self, **values: int | str) -> str:
        """The pattern with `values` put in and `*` for every placeholder not given."""
        return "/".join(
            str(values.get(c[1:-1], "*")) if c.startswith("{") else c for c in self.chunks
        )


_OWN = frozenset({Party.OWN_UAV})

ALIVE = KeySpec("uav/{id}/alive", None, carriage=Carriage.TOKEN, recording=Recording.LIVELINESS)
TELEMETRY = KeySpec("uav/{id}/telemetry", Telemetry, urgency=Urgency.TELEMETRY)
TRACK = KeySpec("uav/{id}/track", Track)
WAYPOINT = KeySpec("uav/{id}/waypoint/{index}", Waypoint)
STATUS = KeySpec("uav/{id}/status", messages.StatusText)
LINK = KeySpec("uav/{id}/link", messages.LinkHealth)
#: Served by its UAV, and relayed by any teammate (its latest put, with the UAV's own
#: signature) to a query that asks for relays: how the ground learns that a UAV frozen
#: or cut off a moment ago is a real one.
STATE = KeySpec(
    "uav/{id}/state", messages.UavState, carriage=Carriage.PUT | Carriage.QUERY,
    reply=messages.UavState, servers=frozenset({Party.OWN_UAV, Party.ANY_UAV}),
    uavs_fetch=True, note="put at the OPM status rate; query reply (relayed on request)",
)  # fmt: skip
#: Signed by its UAV, twice a second while it streams: vouches for its unsigned samples.
DIGEST = KeySpec("uav/{id}/digest", messages.StreamDigest, recording=Recording.UNHEARD)
OPM = KeySpec(
    "uav/{id}/opm", messages.OpmCommand, role=Role.COMMAND, writer=Party.GROUND,
    urgency=Urgency.URGENT,
)  # fmt: skip
CMD_WAYPOINT = KeySpec(
    "uav/{id}/cmd/waypoint", Waypoint, role=Role.COMMAND, carriage=Carriage.QUERY,
    writer=Party.GROUND, recording=Recording.UNHEARD, reply=messages.CommandResult, servers=_OWN,
)  # fmt: skip
CMD_TRACK = KeySpec(
    "uav/{id}/cmd/track", Track, role=Role.COMMAND, carriage=Carriage.QUERY,
    writer=Party.GROUND, recording=Recording.UNHEARD, reply=messages.CommandResult, servers=_OWN,
)  # fmt: skip
#: The ground serves a mission's targets; every UAV relays them to a teammate that was away.
TARGETS = KeySpec(
    "mission/{m}/targets", messages.MissionTargets, role=Role.COMMAND,
    carriage=Carriage.PUT | Carriage.QUERY, writer=Party.GROUND, urgency=Urgency.URGENT,
    reply=messages.MissionTargets, servers=frozenset({Party.GROUND, Party.ANY_UAV}),
    uavs_fetch=True,
)  # fmt: skip
#: Served by its UAV; a standing (a result for a re-plan) is relayed too, with its UAV's
#: signature, by every teammate that heard it, to a query naming it and its plan: an ask
#: for a re-plan in changed air is believed from the asker's own standing only
#: (fleet.consensus.membership), which may outlive the asker.
RESULT = KeySpec(
    "mission/{m}/result/{id}", messages.UavResult, carriage=Carriage.PUT | Carriage.QUERY,
    urgency=Urgency.URGENT, reply=messages.UavResult,
    servers=frozenset({Party.OWN_UAV, Party.ANY_UAV}), uavs_fetch=True,
)  # fmt: skip
ASSIGNMENT = KeySpec(
    "mission/{m}/assignment/{id}", messages.AssignmentReport,
    carriage=Carriage.PUT | Carriage.QUERY, urgency=Urgency.URGENT,
    reply=messages.AssignmentReport, servers=_OWN, uavs_fetch=True,
)  # fmt: skip
#: Heard by subscription only: a teammate that missed one fetches the assignment instead.
REPLAN = KeySpec(
    "mission/{m}/replan/{id}", messages.AssignmentReport, urgency=Urgency.URGENT, note="epoch > 0"
)
#: Served by its UAV, and relayed (with its UAV's signature) by every teammate that
#: heard it, to a query naming it: a claim that a UAV reached a target is believed from
#: that UAV's own outcome only (fleet.mission.claims), which may outlive the UAV.
OUTCOME = KeySpec(
    "mission/{m}/outcome/{id}", messages.TargetOutcome, carriage=Carriage.PUT | Carriage.QUERY,
    urgency=Urgency.URGENT, reply=messages.TargetOutcome,
    servers=frozenset({Party.OWN_UAV, Party.ANY_UAV}), uavs_fetch=True,
)  # fmt: skip
#: Every UAV relays its current mission's abort to a teammate that was away.
ABORT = KeySpec(
    "mission/{m}/abort", messages.MissionAbort, role=Role.COMMAND,
    carriage=Carriage.PUT | Carriage.QUERY, writer=Party.GROUND, urgency=Urgency.URGENT,
    reply=messages.MissionAbort, servers=frozenset({Party.ANY_UAV}), uavs_fetch=True,
)  # fmt: skip
#: A plan proposed by the ground (a routing solver), verified by every UAV before it is
#: adopted (fleet.consensus.proposal); heard by subscription, before the decision.
PROPOSAL = KeySpec(
    "mission/{m}/proposal", messages.PlanProposal, role=Role.COMMAND, writer=Party.GROUND,
    urgency=Urgency.URGENT,
)  # fmt: skip
#: A plan proposed by a UAV that has the CPU (`fleet-onboard --propose`), on its own key
#: and signed by it: a UAV proposes as itself only (fleet.mission.key_check).
UAV_PROPOSAL = KeySpec(
    "mission/{m}/proposal/{id}", messages.PlanProposal, role=Role.COMMAND, urgency=Urgency.URGENT
)

#: Asked with no payload, and answered by each secure router (fleet/transport/router.py),
#: not by a fleet member: one reply per router, so it is asked with every reply kept.
ROUTER_STATE = KeySpec(
    "router/state", None, carriage=Carriage.QUERY, writer=Party.GROUND,
    recording=Recording.UNHEARD, reply=messages.RouterState,
    servers=frozenset({Party.ROUTER}),
)  # fmt: skip

#: The roster of signers (signed by the CA inside, and by the ground that puts it), put
#: by `fleet certs revoke` to a running fleet: revocation without a restart.
ROSTER = KeySpec(
    "roster", messages.RosterDocument, role=Role.COMMAND, writer=Party.GROUND,
    urgency=Urgency.URGENT,
)  # fmt: skip

#: Every key of the fleet. Order is kept wherever keys are listed (schemas, grants).
REGISTRY: tuple[KeySpec, ...] = (
    ALIVE, TELEMETRY, TRACK, WAYPOINT, STATUS, LINK, STATE, DIGEST, OPM, CMD_WAYPOINT, CMD_TRACK,
    TARGETS, RESULT, ASSIGNMENT, REPLAN, OUTCOME, ABORT, PROPOSAL, UAV_PROPOSAL, ROUTER_STATE,
    ROSTER,
)  # fmt: skip

#: The JSON Schema file (without `.schema.json`) of each struct that travels on a key.
SCHEMA_FILES: dict[type[msgspec.Struct], str] = {
    Telemetry: "telemetry",
    Track: "track",
    Waypoint: "waypoint",
    messages.StatusText: "status",
    messages.LinkHealth: "link_health",
    messages.UavState: "uav_state",
    messages.OpmCommand: "opm_command",
    messages.CommandResult: "command_result",
    messages.MissionTargets: "mission_targets",
    messages.UavResult: "uav_result",
    messages.AssignmentReport: "assignment_report",
    messages.MissionAbort: "mission_abort",
    messages.PlanProposal: "plan_proposal",
    messages.TargetOutcome: "target_outcome",
    messages.RouterState: "router_state",
    messages.RosterDocument: "roster",
    messages.StreamDigest: "stream_digest",
}
