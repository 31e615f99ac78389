"""The secure profile's access policy: who may write which keys (Zenoh key-expression
inclusion decides, as the router's access control does)."""

from __future__ import annotations

import pytest
import zenoh

from fleet.mission.access import GROUND, Flow, Message, fleet_policy, uav_identity
from fleet.mission.key_registry import DEFAULT_PREFIX, Carriage
from fleet.mission.key_space import KeySpace
from fleet.mission.signature import SIGNED_KEYS, Delivery, author_of

SPACE = KeySpace()

POLICY = fleet_policy([74, 112], SPACE)


def allowed(identity: str, flow: Flow, message: Message, key: str) -> bool:
    expr = zenoh.KeyExpr(key)
    return any(
        identity in grant.subjects
        and flow in grant.flows
        and message in grant.messages
        and any(zenoh.KeyExpr(allow).includes(expr) for allow in grant.key_exprs)
        for grant in POLICY
    )


def puts(identity: str, key: str) -> bool:
    return allowed(identity, Flow.INGRESS, Message.PUT, key)


@pytest.mark.parametrize(
    "key",
    [
        SPACE.mission_targets(5),
        SPACE.mission_abort(5),
        SPACE.opm(112),
        SPACE.telemetry(112),
        SPACE.mission_result(5, 112),
        SPACE.mission_assignment(5, 112),
        SPACE.mission_replan(5, 112),
        "fleet/other",
    ],
)
def test_uav_74_cannot_write_for_others_or_command(key: str) -> None:
    assert not puts(uav_identity(74), key)


@pytest.mark.parametrize(
    "key",
    [
        SPACE.telemetry(74),
        SPACE.mission_result(5, 74),
        SPACE.mission_assignment(5, 74),
        SPACE.mission_replan(5, 74),
    ],
)
def test_uav_74_writes_its_own_keys(key: str) -> None:
    assert puts(uav_identity(74), key)


def test_only_the_ground_commands() -> None:
    for key in (SPACE.mission_targets(5), SPACE.mission_abort(5), SPACE.opm(74)):
        assert puts(GROUND, key)
    command = SPACE.command(112, "waypoint")
    assert allowed(GROUND, Flow.INGRESS, Message.QUERY, command)
    assert not allowed(uav_identity(74), Flow.INGRESS, Message.QUERY, command)
    assert not puts(GROUND, SPACE.mission_result(5, 74))


def test_liveliness_only_for_ones_own_token() -> None:
    token = Message.LIVELINESS_TOKEN
    assert allowed(uav_identity(74), Flow.INGRESS, token, SPACE.alive(74))
    assert not allowed(uav_identity(74), Flow.INGRESS, token, SPACE.alive(299))
    assert not allowed(GROUND, Flow.INGRESS, token, SPACE.alive(74))


def test_everyone_reads_the_whole_tree_so_a_fleet_wide_subscription_is_allowed() -> None:
    for identity in (GROUND, uav_identity(74), uav_identity(112)):
        assert allowed(identity, Flow.INGRESS, Message.DECLARE_SUBSCRIBER, "fleet/**")
        assert allowed(identity, Flow.EGRESS, Message.PUT, SPACE.telemetry(74))
    assert not allowed("uav-999", Flow.EGRESS, Message.PUT, SPACE.telemetry(74))


def test_the_policy_follows_the_key_space_given() -> None:
    lab = KeySpace("lab")
    exprs = {expr for grant in fleet_policy([74], lab) for expr in grant.key_exprs}
    assert "lab/uav/74/**" in exprs and "lab/mission/*/targets" in exprs
    assert not any(expr.startswith(f"{DEFAULT_PREFIX}/") for expr in exprs)


def test_who_must_sign_a_key_is_who_the_acl_lets_write_it() -> None:
    """One source: for every signed key, the author a receiver demands
    (`fleet.mission.signature`) is the identity the router lets put it (or ask it, for a
    command query), and no other fleet identity may (routers aside; a UAV in its own
    tree)."""
    identities = (GROUND, uav_identity(74), uav_identity(112))
    for spec in SIGNED_KEYS:
        key = SPACE.key(spec, id=112, m=5, index=0)
        how, message = (
            (Delivery.PUT, Message.PUT)
            if Carriage.PUT in spec.carriage
            else (Delivery.QUERY, Message.QUERY)
        )
        author = author_of(SPACE, key, how)
        assert author is not None, key
        writers = {i for i in identities if allowed(i, Flow.INGRESS, message, key)}
        if message is Message.PUT:
            # The ACL also lets a UAV write anywhere in its own tree (its OPM key too):
            # there the signature is what keeps the command the ground's.
            assert author in writers and writers - {author} <= {uav_identity(112)}, key
        else:  # the ground may query every key; only a command query is signed
            assert author == GROUND and GROUND in writers, key
