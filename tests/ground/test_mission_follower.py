"""Following a mission that gets superseded: `MissionFollower` against a real router
on loopback, with other Zenoh sessions standing in for another ground and the UAVs."""

from __future__ import annotations

import zenoh

from fleet.mission import keys
from fleet.transport import bus_codec
from ground.mission_follower import MissionFollower
from ground.mission_ids import TargetsServer
from tests.ground.mission_samples import (
    TIMEOUT_S,
    mission,
)
from tests.support.waiting import wait_until


def test_a_later_mission_for_the_team_supersedes_the_followed_one(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with MissionFollower(session, 40, team=(7, 8)) as follower:
        # Another team's later mission is no concern of this one.
        rival.put(
            keys.mission_targets(41),
            bus_codec.encode(mission(41, team=(9,))),
            encoding=bus_codec.ENCODING,
        )

        def put_later_mission() -> bool:
            # Put again until heard: the follower's subscription reaches the router
            # asynchronously, and a put before it arrives is not delivered.
            rival.put(
                keys.mission_targets(43),
                bus_codec.encode(mission(43, team=(8, 9))),
                encoding=bus_codec.ENCODING,
            )
            return follower.wait_superseded(0.2) is not None

        wait_until(put_later_mission, 10.0, "the later mission")
        assert follower.superseded_by == 43
        # Waiting for commitments of a superseded mission ends at once.
        assert follower.wait_committed((7, 8), timeout_s=30.0, fetch_every_s=1.0) is False


def test_a_later_mission_the_uavs_serve_is_found_by_the_fetch(
    session: zenoh.Session, rival: zenoh.Session
) -> None:
    with MissionFollower(session, 50, team=(7,)) as follower:
        with TargetsServer(rival, mission(52, team=(7,))):
            follower.fetch(TIMEOUT_S)
        assert follower.superseded_by == 52
        follower.note_later_mission(51)  # an older later one changes nothing
        assert follower.superseded_by == 52
