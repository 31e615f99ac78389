"""Who may do what on the fleet's key space: the access policy of the secure profile.

Pure data: each identity (a certificate's common name) gets grants, each a set of
message kinds, a direction and the key expressions they cover, built from
`fleet.mission.keys`. `fleet.transport.acl` turns them into Zenoh's `access_control`
configuration; anything no grant covers is denied.

The policy, from the router's point of view (ingress: from that client into the router;
egress: from the router out to that client):

* every fleet identity may *read* the fleet's key space: subscribe, query, receive;
* only the ground may *command*: put missions, aborts and OPM commands, query the
  waypoint and track command queryables, answer mission-targets queries;
* UAV n may only *write* as UAV n: publish under `fleet/uav/n/**`, its own mission
  results and assignments, declare its own liveliness token, answer queries for its own
  keys, and serve queries (queryables) for its own keys and the mission space.

Zenoh allows a message only when an allow rule *includes* its key expression, so the
reading grants cover the whole `fleet/**` tree: a subscription to `fleet/**` would be
refused by grants that only cover sub-trees.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from fleet.mission import keys

GROUND = "ground"
ROUTER = "router"
ADMIN_SPACE = "@/**"


def all_fleet() -> str:
    """Every key of the fleet (the prefix is read when used, never copied at import)."""
    return f"{keys.PREFIX}/**"


def uav_identity(uav_id: int) -> str:
    """A UAV's identity: its certificate's common name."""
    return f"uav-{uav_id}"


class Message(StrEnum):
    """Zenoh's access-control message kinds (zenoh 1.x names)."""

    PUT = "put"
    DELETE = "delete"
    DECLARE_SUBSCRIBER = "declare_subscriber"
    QUERY = "query"
    DECLARE_QUERYABLE = "declare_queryable"
    REPLY = "reply"
    LIVELINESS_TOKEN = "liveliness_token"
    DECLARE_LIVELINESS_SUBSCRIBER = "declare_liveliness_subscriber"
    LIVELINESS_QUERY = "liveliness_query"


class Flow(StrEnum):
    INGRESS = "ingress"  #: from the client into the router
    EGRESS = "egress"  #: from the router out to the client


@dataclass(frozen=True)
class Grant:
    """Identities `subjects` may send (or receive) `messages` on `key_exprs`."""

    name: str
    subjects: tuple[str, ...]
    flows: tuple[Flow, ...]
    messages: tuple[Message, ...]
    key_exprs: tuple[str, ...]


#: What every fleet member receives from the router: all it may read.
_RECEIVE = tuple(Message)
#: What every fleet member may ask the router for, without writing anything.
_READ = (
    Message.DECLARE_SUBSCRIBER,
    Message.DECLARE_LIVELINESS_SUBSCRIBER,
    Message.LIVELINESS_QUERY,
)


def _uav_grants(uav_id: int) -> list[Grant]:
    me = (uav_identity(uav_id),)
    own = (
        keys.uav(uav_id, "**"),
        f"{keys.PREFIX}/mission/*/result/{uav_id}",
        f"{keys.PREFIX}/mission/*/assignment/{uav_id}",
        f"{keys.PREFIX}/mission/*/replan/{uav_id}",
        f"{keys.PREFIX}/mission/*/outcome/{uav_id}",
    )
    ingress = (Flow.INGRESS,)
    return [
        Grant(f"uav-{uav_id}-publish", me, ingress, (Message.PUT, Message.REPLY), own),
        # A UAV relays its current mission's targets and abort by query (never by put):
        # how a teammate that was away learns the live mission and that it was aborted.
        Grant(
            f"uav-{uav_id}-relay",
            me,
            ingress,
            (Message.REPLY,),
            (keys.ALL_MISSION_TARGETS, keys.ALL_MISSION_ABORTS),
        ),
        Grant(
            f"uav-{uav_id}-alive", me, ingress, (Message.LIVELINESS_TOKEN,), (keys.alive(uav_id),)
        ),
        Grant(
            f"uav-{uav_id}-serve",
            me,
            ingress,
            (Message.DECLARE_QUERYABLE,),
            (keys.uav(uav_id, "**"), keys.ALL_MISSION_KEYS),
        ),
        Grant(
            f"uav-{uav_id}-fetch",
            me,
            ingress,
            (Message.QUERY,),
            (
                keys.ALL_MISSION_TARGETS,
                keys.ALL_MISSION_RESULTS,
                keys.ALL_MISSION_ASSIGNMENTS,
                keys.ALL_MISSION_OUTCOMES,
                keys.ALL_MISSION_ABORTS,
                keys.ALL_STATE,
            ),
        ),
    ]


def _ground_grants() -> list[Grant]:
    me = (GROUND,)
    ingress = (Flow.INGRESS,)
    commands = (
        keys.ALL_MISSION_TARGETS,
        keys.ALL_MISSION_ABORTS,
        f"{keys.PREFIX}/uav/*/opm",
    )
    return [
        Grant("ground-command", me, ingress, (Message.PUT,), commands),
        Grant("ground-query", me, ingress, (Message.QUERY,), (all_fleet(), ADMIN_SPACE)),
        Grant(
            "ground-serve-targets",
            me,
            ingress,
            (Message.DECLARE_QUERYABLE, Message.REPLY),
            (keys.ALL_MISSION_TARGETS,),
        ),
    ]


def fleet_policy(uav_ids: list[int]) -> list[Grant]:
    """Every grant of a fleet of `uav_ids` with one ground and its routers.

    Everything else is denied.
    """
    members = (GROUND, *(uav_identity(u) for u in uav_ids))
    both = (Flow.INGRESS, Flow.EGRESS)
    grants = [
        # Routers relay everything between their clients and each other.
        Grant("router-relay", (ROUTER,), both, tuple(Message), ("**",)),
        Grant("fleet-receive", members, (Flow.EGRESS,), _RECEIVE, (all_fleet(),)),
        Grant("fleet-read", members, (Flow.INGRESS,), _READ, (all_fleet(),)),
        *_ground_grants(),
    ]
    for uav_id in uav_ids:
        grants += _uav_grants(uav_id)
    return grants
