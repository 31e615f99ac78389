"""A mission's acknowledgement is verified by content (`ground.mission_ack`): a UAV
holding other targets under the id sent is a collision, not a delivery."""

from __future__ import annotations

import msgspec
import pytest

from fleet.consensus.targets_digest import struct_digest, targets_digest
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionTargets, Target
from fleet.transport.memory import MemoryNetwork
from ground.mission_ack import MissionCollision, wait_acknowledged
from tests.ground.memory_fleet import MemoryUav
from tests.ground.mission_samples import OTHER_TARGETS, mission

SPACE = KeySpace()


def test_delivery_is_read_from_the_uavs_states() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    seven, eight = MemoryUav(network, 7), MemoryUav(network, 8)
    seven.fly(mission(9))
    seen = wait_acknowledged(ground, SPACE, mission(9), 0.1)
    assert (seen.got, seen.collided) == ({7}, set())
    eight.fly(mission(10))  # a later mission counts as delivered
    assert wait_acknowledged(ground, SPACE, mission(9), 0.1).got == {7, 8}


def test_a_uav_holding_other_targets_under_the_id_is_a_collision() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    MemoryUav(network, 7).fly(mission(3, OTHER_TARGETS))  # another ground's mission 3
    MemoryUav(network, 8).fly(mission(3))
    sent = mission(3)
    seen = wait_acknowledged(ground, SPACE, sent, 5.0)  # returns once each UAV is judged
    assert (seen.got, seen.collided) == ({8}, {7})
    collision = seen.collision(sent)
    assert isinstance(collision, MissionCollision)
    assert "UAV 7 holds another mission under id 3" in str(collision)
    assert wait_acknowledged(ground, SPACE, mission(3, OTHER_TARGETS), 5.0).collided == {8}


def test_an_older_onboard_without_a_digest_is_believed_on_the_id() -> None:
    network = MemoryNetwork()
    MemoryUav(network, 7).fly(mission(3, OTHER_TARGETS, team=(7,)), digest=False)
    seen = wait_acknowledged(network.bus(), SPACE, mission(3, team=(7,)), 0.1)
    assert (seen.got, seen.collided) == ({7}, set())
    assert seen.collision(mission(3)) is None


@pytest.mark.parametrize(
    "changed",
    [
        mission(3, team=(7,)),
        mission(4),
        mission(3, (Target(42.36, -71.09, 121.0), *OTHER_TARGETS)),
        MissionTargets(3, (7, 8), mission(3).targets, deadline_s=9.0),
    ],
)
def test_the_digest_tells_any_change_apart(changed: MissionTargets) -> None:
    assert targets_digest(mission(3)) == targets_digest(mission(3))
    assert len(targets_digest(mission(3))) == 64
    assert targets_digest(changed) != targets_digest(mission(3))


def test_a_field_added_at_its_default_leaves_the_digest_as_it_was() -> None:
    """An onboard whose MissionTargets gained a field (last, with a default) agrees with
    a ground that does not know it, as long as the field is unused."""
    fields = [(f.name, f.type, f.default) for f in msgspec.structs.fields(MissionTargets)]
    later = msgspec.defstruct(
        "MissionTargets", [*fields, ("later", int, 0)], frozen=True, kw_only=True
    )
    sent = mission(3)
    values = msgspec.structs.asdict(sent)
    assert struct_digest(later(**values)) == targets_digest(sent)
    assert struct_digest(later(**values, later=1)) != targets_digest(sent)
