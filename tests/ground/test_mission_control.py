"""The ground's mission commands and status (`ground.mission_control`) on the in-memory bus."""

from __future__ import annotations

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionAbort, MissionTargets, OpmCommand, UavResult
from fleet.transport import bus_codec
from fleet.transport.bus import BusSample
from fleet.transport.memory import MemoryNetwork
from ground.mission_control import (
    MissionError,
    mission_status,
    mission_targets_of,
    publish_targets,
    send_abort,
    send_opm,
)
from tests.ground.memory_fleet import MemoryUav
from tests.ground.mission_samples import mission

SPACE = KeySpace()


def heard(network: MemoryNetwork, key_expr: str) -> list[BusSample]:
    samples: list[BusSample] = []
    network.bus().subscribe(key_expr, samples.append)
    return samples


def test_the_commands_are_put_on_their_keys() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    samples = heard(network, f"{SPACE.prefix}/**")
    publish_targets(ground, SPACE, mission(4))
    send_abort(ground, SPACE, 4, uav=7)
    send_opm(ground, SPACE, 7, False, 0.5)
    assert [s.key for s in samples] == [
        SPACE.mission_targets(4),
        SPACE.mission_abort(4),
        SPACE.opm(7),
    ]
    assert bus_codec.decode(samples[0].payload, MissionTargets, samples[0].key) == mission(4)
    assert bus_codec.decode(samples[1].payload, MissionAbort, samples[1].key) == MissionAbort(4, 7)
    opm = bus_codec.decode(samples[2].payload, OpmCommand, samples[2].key)
    assert (opm.enabled, opm.status_rate_hz) == (False, 0.5)


def test_a_missions_status_is_what_the_team_serves() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    with pytest.raises(MissionError, match="mission 5: no UAV or ground answers"):
        mission_targets_of(ground, SPACE, 5, 0.1)
    result = UavResult(5, 7, (12.0, 30.0))
    MemoryUav(network, 7).fly(mission(5), result)
    assert mission_targets_of(ground, SPACE, 5, 0.1) == mission(5)
    outcome = mission_status(ground, SPACE, 5, 0.1)
    assert outcome.results == {7: result}
    assert outcome.lost == {8}  # on the team, but no state answers for it
    assert outcome.phases == {7: "computing"}
