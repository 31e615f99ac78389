"""What each fleet key is given by the modules that describe keys: its QoS, whether it
is a command, its recording channel, the ids parsed from it, and the access policy.

The expected values are literal: they were taken from the hand-written modules before
those were derived from the key registry (fleet.mission.key_registry), so the registry
is held to the behaviour it replaced.
"""

from __future__ import annotations

import pytest

from fleet.mission.access import fleet_policy
from fleet.mission.key_check import KeyIds, parse_key
from fleet.mission.key_space import DEFAULT_SPACE
from fleet.recording import channels
from fleet.transport.bus_qos import ORDINARY, TELEMETRY, URGENT, Qos, qos_for

U74 = KeyIds(74, None, None)

#: key -> (QoS, a command?, recorded schema name, recorded pattern, parsed ids)
KEYS: dict[str, tuple[Qos, bool, str, str, KeyIds]] = {
    "fleet/uav/74/alive": (ORDINARY, False, "", "fleet/uav/74/alive", U74),
    "fleet/uav/74/telemetry": (
        TELEMETRY, False, "Telemetry", "fleet/uav/*/telemetry", U74,
    ),
    "fleet/uav/74/track": (ORDINARY, False, "Track", "fleet/uav/*/track", U74),
    "fleet/uav/74/waypoint/3": (
        ORDINARY, False, "Waypoint", "fleet/uav/*/waypoint/*", KeyIds(74, None, 3),
    ),
    "fleet/uav/74/status": (
        ORDINARY, False, "StatusText", "fleet/uav/*/status", U74,
    ),
    "fleet/uav/74/link": (ORDINARY, False, "LinkHealth", "fleet/uav/*/link", U74),
    "fleet/uav/74/state": (ORDINARY, False, "UavState", "fleet/uav/*/state", U74),
    "fleet/uav/74/opm": (URGENT, True, "OpmCommand", "fleet/uav/*/opm", U74),
    "fleet/uav/74/cmd/waypoint": (
        ORDINARY, True, "", "fleet/uav/74/cmd/waypoint", U74,
    ),
    "fleet/uav/74/cmd/track": (ORDINARY, True, "", "fleet/uav/74/cmd/track", U74),
    "fleet/mission/5/targets": (
        URGENT, True, "MissionTargets", "fleet/mission/*/targets", KeyIds(None, 5, None),
    ),
    "fleet/mission/5/result/74": (
        URGENT, False, "UavResult", "fleet/mission/*/result/*", KeyIds(74, 5, None),
    ),
    "fleet/mission/5/assignment/74": (
        URGENT, False, "AssignmentReport", "fleet/mission/*/assignment/*", KeyIds(74, 5, None),
    ),
    "fleet/mission/5/replan/74": (
        URGENT, False, "AssignmentReport", "fleet/mission/*/replan/*", KeyIds(74, 5, None),
    ),
    "fleet/mission/5/outcome/74": (
        URGENT, False, "TargetOutcome", "fleet/mission/*/outcome/*", KeyIds(74, 5, None),
    ),
    "fleet/mission/5/abort": (
        URGENT, True, "MissionAbort", "fleet/mission/*/abort", KeyIds(None, 5, None),
    ),
    "fleet/mission/5/proposal": (
        URGENT, True, "PlanProposal", "fleet/mission/*/proposal", KeyIds(None, 5, None),
    ),
    "fleet/mission/5/proposal/74": (
        URGENT, True, "PlanProposal", "fleet/mission/*/proposal/*", KeyIds(74, 5, None),
    ),
}  # fmt: skip


@pytest.mark.parametrize("key", sorted(KEYS))
def test_qos_of_every_key(key: str) -> None:
    assert qos_for(key) == KEYS[key][0]


@pytest.mark.parametrize("key", sorted(KEYS))
def test_commands_of_every_key(key: str) -> None:
    assert channels.is_command(key) is KEYS[key][1]


@pytest.mark.parametrize("key", sorted(KEYS))
def test_recording_channel_of_every_key(key: str) -> None:
    spec = channels.channel_for(key)
    assert (spec.topic, spec.schema_name, spec.pattern) == (key, *KEYS[key][2:4])
    assert bool(spec.schema) is bool(spec.schema_name)


@pytest.mark.parametrize("key", sorted(KEYS))
def test_ids_parsed_from_every_key(key: str) -> None:
    assert parse_key(key) == KEYS[key][4]


_ALL = (
    "put", "delete", "declare_subscriber", "query", "declare_queryable", "reply",
    "liveliness_token", "declare_liveliness_subscriber", "liveliness_query",
)  # fmt: skip
_READ = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")

#: fleet_policy([74]): (name, subjects, flows, messages, key expressions in any order)
POLICY_74 = [
    ("fleet-receive", ("ground", "uav-74", "router-74"), ("egress",), _ALL, {"fleet/**"}),
    ("fleet-read", ("ground", "uav-74", "router-74"), ("ingress",), _READ, {"fleet/**"}),
    (
        "ground-command", ("ground",), ("ingress",), ("put",),
        # The roster: a revocation put to the running fleet; a proposed plan.
        {
            "fleet/mission/*/abort", "fleet/mission/*/targets", "fleet/uav/*/opm",
            "fleet/roster", "fleet/mission/*/proposal",
        },
    ),
    ("ground-query", ("ground",), ("ingress",), ("query",), {"@/**", "fleet/**"}),
    (
        "ground-serve-targets", ("ground",), ("ingress",), ("declare_queryable", "reply"),
        {"fleet/mission/*/targets"},
    ),
    (
        "uav-74-publish", ("uav-74", "router-74"), ("ingress",), ("put", "reply"),
        {
            "fleet/mission/*/assignment/74", "fleet/mission/*/outcome/74",
            "fleet/mission/*/replan/74", "fleet/mission/*/result/74", "fleet/uav/74/**",
            # Its own proposed plan (fleet-onboard --propose), never another's.
            "fleet/mission/*/proposal/74",
        },
    ),
    (
        "uav-74-relay", ("uav-74", "router-74"), ("ingress",), ("reply",),
        # A teammate's outcome, relayed with its own signature (fleet.mission.claims);
        # a teammate's latest state, the same way (how a frozen UAV stays on the team);
        # a teammate's standing, the same way (an ask is believed from its asker alone).
        {
            "fleet/mission/*/abort", "fleet/mission/*/targets", "fleet/mission/*/outcome/*",
            "fleet/mission/*/result/*", "fleet/uav/*/state",
        },
    ),
    (
        "uav-74-alive", ("uav-74", "router-74"), ("ingress",), ("liveliness_token",),
        {"fleet/uav/74/alive"},
    ),
    (
        "uav-74-serve", ("uav-74", "router-74"), ("ingress",), ("declare_queryable",),
        {"fleet/mission/**", "fleet/uav/74/**", "fleet/uav/*/state"},
    ),
    (
        "uav-74-fetch", ("uav-74", "router-74"), ("ingress",), ("query",),
        {
            "fleet/mission/*/abort", "fleet/mission/*/assignment/*", "fleet/mission/*/outcome/*",
            "fleet/mission/*/result/*", "fleet/mission/*/targets", "fleet/uav/*/state",
        },
    ),
    # Added with the routers' state: UAV 74's router answers for itself.
    (
        "routers-serve", ("router-74",), ("ingress",), ("declare_queryable", "reply"),
        {"fleet/router/state"},
    ),
]  # fmt: skip


def test_the_access_policy_grants_what_it_always_granted() -> None:
    found = [
        (
            grant.name,
            grant.subjects,
            tuple(str(flow) for flow in grant.flows),
            tuple(str(message) for message in grant.messages),
            set(grant.key_exprs),
        )
        for grant in fleet_policy([74], DEFAULT_SPACE)
    ]
    assert found == POLICY_74
