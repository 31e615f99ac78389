"""Who may do what on the fleet's key space: the access policy of the secure profile.

Pure data: each identity (a certificate's common name) gets grants, each a set of
message kinds, a direction and the key expressions they cover, derived from who writes
and serves each key in the key registry (`fleet.mission.key_registry`).
`fleet.transport.acl` turns them into Zenoh's `access_control` configuration; anything
no grant covers is denied.

The policy, from the router's point of view (ingress: from that client into the router;
egress: from the router out to that client):

* every fleet identity may *read* the fleet's key space: subscribe, query, receive;
* only the ground may *command*: put missions, aborts and OPM commands, query the
  waypoint and track command queryables, answer mission-targets queries;
* UAV n may only *write* as UAV n: publish under `{prefix}/uav/n/**`, its own mission
  results and assignments, declare its own liveliness token, answer queries for its own
  keys, and serve queries (queryables) for its own keys and the mission space; it may
  also relay, by reply only, a teammate's state and outcome (each believed for its
  author only, by its signature: `fleet.mission.signature`).
* UAV n's own router (`router-n`, in a router-per-UAV mesh) has UAV n's rights and no
  more: a captured aircraft's router speaks for that aircraft only;
* every UAV's router may answer for itself where routers serve (its refused links), as
  the ground's router may (it relays everything);
* the ground's router (`router`) relays everything, in the ACL of the other routers
  only: no router grants its own identity anything, so the router identity used by a
  client of the ground's router gets nothing (and the ground's router is the only one
  that holds `router.key`).

Zenoh allows a message only when an allow rule *includes* its key expression, so the
reading grants cover the whole `{prefix}/**` tree: a subscription to `{prefix}/**` would
be refused by grants that only cover sub-trees.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from fleet.mission.key_registry import REGISTRY, Carriage, KeySpec, Party, Role
from fleet.mission.key_space import KeySpace

GROUND = "ground"
ROUTER = "router"
ADMIN_SPACE = "@/**"


def uav_identity(uav_id: int) -> str:
    """A UAV's identity: its certificate's common name."""
    return f"uav-{uav_id}"


def uav_router_identity(uav_id: int) -> str:
    """The identity of UAV `uav_id`'s own router (`--topology router-per-uav`)."""
    return f"{ROUTER}-{uav_id}"


def is_router_identity(name: str) -> bool:
    """Whether `name` is a router's identity: the only ones whose certificates may serve."""
    return name == ROUTER or name.startswith(f"{ROUTER}-")


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


_UAVS = frozenset({Party.OWN_UAV, Party.ANY_UAV})


def _wildcards(space: KeySpace, specs: list[KeySpec], **ids: int) -> tuple[str, ...]:
    return tuple(space.key(spec, **ids) for spec in specs)


def _uav_grants(uav_id: int, space: KeySpace, own: str) -> list[Grant]:
    me = tuple(i for i in (uav_identity(uav_id), uav_router_identity(uav_id)) if i != own)
    written = [s for s in REGISTRY if s.writer is Party.OWN_UAV]
    # A UAV owns its whole sub-tree (its replies to the ground's commands and state
    # queries included); under the mission tree only the keys that name it.
    own_tree = (space.uav_tree(uav_id),) if any(s.tree == "uav" for s in written) else ()
    own_mission = [s for s in written if s.tree == "mission" and Carriage.PUT in s.carriage]
    tokens = [s for s in written if Carriage.TOKEN in s.carriage]
    # A UAV declares its queryables by wildcard: its own sub-tree, the keys of its
    # teammates' sub-trees it relays (their states), and the mission tree where it
    # answers for its own keys and relays the ground's.
    served = {s.tree for s in REGISTRY if s.servers & _UAVS}
    relayed_uav_keys = [s for s in REGISTRY if s.tree == "uav" and Party.ANY_UAV in s.servers]
    serve_trees = (
        *((space.uav_tree(uav_id),) if "uav" in served else ()),
        *_wildcards(space, relayed_uav_keys),
        *((space.all_mission_keys,) if "mission" in served else ()),
    )
    ingress = (Flow.INGRESS,)
    return [
        Grant(
            f"uav-{uav_id}-publish",
            me,
            ingress,
            (Message.PUT, Message.REPLY),
            (*own_tree, *_wildcards(space, own_mission, id=uav_id)),
        ),
        # A UAV relays its current mission's targets and abort by query (never by put):
        # how a teammate that was away learns the live mission and that it was aborted;
        # and a teammate's outcome and latest state, each as its author signed it.
        Grant(
            f"uav-{uav_id}-relay",
            me,
            ingress,
            (Message.REPLY,),
            _wildcards(space, [s for s in REGISTRY if Party.ANY_UAV in s.servers]),
        ),
        Grant(
            f"uav-{uav_id}-alive",
            me,
            ingress,
            (Message.LIVELINESS_TOKEN,),
            _wildcards(space, tokens, id=uav_id),
        ),
        Grant(f"uav-{uav_id}-serve", me, ingress, (Message.DECLARE_QUERYABLE,), serve_trees),
        Grant(
            f"uav-{uav_id}-fetch",
            me,
            ingress,
            (Message.QUERY,),
            _wildcards(space, [s for s in REGISTRY if s.uavs_fetch]),
        ),
    ]


def _ground_grants(space: KeySpace) -> list[Grant]:
    me = (GROUND,)
    ingress = (Flow.INGRESS,)
    commands = [
        s
        for s in REGISTRY
        if s.writer is Party.GROUND and s.role is Role.COMMAND and Carriage.PUT in s.carriage
    ]
    return [
        Grant("ground-command", me, ingress, (Message.PUT,), _wildcards(space, commands)),
        Grant("ground-query", me, ingress, (Message.QUERY,), (space.everything, ADMIN_SPACE)),
        Grant(
            "ground-serve-targets",
            me,
            ingress,
            (Message.DECLARE_QUERYABLE, Message.REPLY),
            _wildcards(space, [s for s in REGISTRY if Party.GROUND in s.servers]),
        ),
    ]


def _router_grants(uav_ids: list[int], space: KeySpace, own: str) -> list[Grant]:
    routers = tuple(r for r in map(uav_router_identity, uav_ids) if r != own)
    served = _wildcards(space, [s for s in REGISTRY if Party.ROUTER in s.servers])
    if not (routers and served):
        return []
    messages = (Message.DECLARE_QUERYABLE, Message.REPLY)
    return [Grant("routers-serve", routers, (Flow.INGRESS,), messages, served)]


def fleet_policy(uav_ids: list[int], space: KeySpace, own: str = ROUTER) -> list[Grant]:
    """Every grant the router with identity `own` enforces, in a fleet of `uav_ids` with
    one ground, its router and maybe a router per UAV, on the keys of `space`.

    Everything else is denied; `own` itself is granted nothing.
    """
    members = tuple(
        i for u in uav_ids for i in (uav_identity(u), uav_router_identity(u)) if i != own
    )
    members = (GROUND, *members)
    both = (Flow.INGRESS, Flow.EGRESS)
    relays = tuple(i for i in (ROUTER,) if i != own)
    grants = [
        # The ground's router relays everything, to the UAVs' routers.
        *([Grant("router-relay", relays, both, tuple(Message), ("**",))] if relays else []),
        Grant("fleet-receive", members, (Flow.EGRESS,), _RECEIVE, (space.everything,)),
        Grant("fleet-read", members, (Flow.INGRESS,), _READ, (space.everything,)),
        *_ground_grants(space),
    ]
    for uav_id in uav_ids:
        grants += _uav_grants(uav_id, space, own)
    return grants + _router_grants(uav_ids, space, own)
