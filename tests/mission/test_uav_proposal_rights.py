"""A UAV's proposed plan: on its own key, signed with its own key, as itself only.

Three locks, each checked here: the router's access policy lets UAV n put on
`mission/{m}/proposal/n` and on no other UAV's (nor the ground's) proposal key; the
signature on that key must be UAV n's (a teammate's signature is not entitled, even a
valid one); and the key must vouch for the proposer the message names (a UAV cannot
propose as another UAV, nor as the ground)."""

from __future__ import annotations

import msgspec
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from fleet.mission.access import fleet_policy
from fleet.mission.key_check import WrongKey, check_key
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MISSION_MANAGER, PlanProposal
from fleet.mission.objective import Objective
from fleet.mission.signature import Delivery, Refusal, Roster, sign, verify
from fleet.transport.acl import access_control

SPACE = KeySpace()
NOW = 1_800_000_000 * 1_000_000_000
KEYS = {name: Ed25519PrivateKey.generate() for name in ("ground", "uav-74", "uav-112")}
ROSTER = Roster({name: key.public_key() for name, key in KEYS.items()})


def _proposal(proposer: int) -> PlanProposal:
    return PlanProposal(
        mission=5,
        proposer=proposer,
        digest="0123456789abcdef",
        objective=Objective.MIN_MAX,
        queues={74: (0, 1), 112: (2,)},
    )


def _signed(author: str, key: str, payload: bytes) -> bytes:
    return sign(KEYS[author], author, key, payload, NOW)


def test_a_uav_signed_proposal_on_its_own_key_is_believed() -> None:
    key = SPACE.uav_proposal(5, 74)
    payload = msgspec.json.encode(_proposal(74))
    envelope, refusal = verify(
        ROSTER, SPACE, key, payload, _signed("uav-74", key, payload), Delivery.PUT
    )
    assert refusal is None and envelope is not None and envelope.author == "uav-74"
    check_key(key, _proposal(74))  # the key vouches for the proposer it names


@pytest.mark.parametrize(
    ("author", "key"),
    [
        # Another UAV's key signing for this UAV's slot: a valid signature, not entitled.
        ("uav-112", SPACE.uav_proposal(5, 74)),
        # A UAV on the ground's proposal key.
        ("uav-74", SPACE.mission_proposal(5)),
        # The ground on a UAV's key: each key has one writer.
        ("ground", SPACE.uav_proposal(5, 74)),
    ],
)
def test_a_proposal_signed_by_another_than_its_keys_writer_is_refused(
    author: str, key: str
) -> None:
    payload = msgspec.json.encode(_proposal(74))
    envelope, refusal = verify(
        ROSTER, SPACE, key, payload, _signed(author, key, payload), Delivery.PUT
    )
    assert refusal is Refusal.NOT_ENTITLED and envelope is not None


def test_an_unsigned_or_tampered_proposal_is_refused() -> None:
    key = SPACE.uav_proposal(5, 74)
    payload = msgspec.json.encode(_proposal(74))
    attachment = _signed("uav-74", key, payload)
    assert verify(ROSTER, SPACE, key, payload, b"", Delivery.PUT)[1] is Refusal.UNSIGNED
    other = msgspec.json.encode(msgspec.structs.replace(_proposal(74), queues={74: (0, 1, 2)}))
    assert verify(ROSTER, SPACE, key, other, attachment, Delivery.PUT)[1] is Refusal.BAD_SIGNATURE


@pytest.mark.parametrize(
    ("key", "proposer", "why"),
    [
        (SPACE.uav_proposal(5, 74), 112, "proposer 112, not the key's 74"),
        (SPACE.uav_proposal(5, 74), MISSION_MANAGER, f"proposer {MISSION_MANAGER}"),
        (SPACE.mission_proposal(5), 74, f"not the key's {MISSION_MANAGER}"),
        (SPACE.uav_proposal(6, 74), 74, "mission 5, not the key's 6"),
    ],
)
def test_a_proposer_its_key_does_not_vouch_for_is_refused(
    key: str, proposer: int, why: str
) -> None:
    with pytest.raises(WrongKey, match=why):
        check_key(key, _proposal(proposer))
    check_key(SPACE.mission_proposal(5), _proposal(MISSION_MANAGER))


def test_the_routers_acl_lets_a_uav_put_its_own_proposal_only() -> None:
    rules = {rule["id"]: rule for rule in access_control(fleet_policy([74, 112], SPACE))["rules"]}
    puts = {
        name: set(rule["key_exprs"]) for name, rule in rules.items() if "put" in rule["messages"]
    }
    assert "fleet/mission/*/proposal/74" in puts["uav-74-publish"]
    assert "fleet/mission/*/proposal/112" in puts["uav-112-publish"]
    for name, exprs in puts.items():
        proposals = {e for e in exprs if "/proposal" in e}
        if name.startswith("uav-74"):
            assert proposals == {"fleet/mission/*/proposal/74"}, name
        elif name.startswith("uav-112"):
            assert proposals == {"fleet/mission/*/proposal/112"}, name
        elif name == "ground-command":
            assert proposals == {"fleet/mission/*/proposal"}, name
