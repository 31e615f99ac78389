"""The fleet as the ground sees it (`ground.fleet_view`), on the in-memory bus."""

from __future__ import annotations

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import StatusText
from fleet.mission.phase import Severity
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus import Bus, DelegatingBus
from fleet.transport.memory import MemoryNetwork
from ground.alerts import StatusRecord
from ground.fleet_view import FleetView, fleet_snapshot, live_uav_ids, query_states
from tests.ground.memory_fleet import MemoryUav

SPACE = KeySpace()


def test_the_live_uavs_are_those_holding_a_token_with_what_their_state_says() -> None:
    network = MemoryNetwork()
    ground = network.bus()
    uavs = [MemoryUav(network, 112), MemoryUav(network, 74)]
    assert live_uav_ids(ground, SPACE, 0.1) == [74, 112]
    assert sorted(query_states(ground, SPACE, 0.1)) == [74, 112]
    views = fleet_snapshot(ground, SPACE, 0.1)
    assert [(v.id, v.enabled, v.status_rate_hz) for v in views] == [
        (74, True, 1.0),
        (112, True, 1.0),
    ]
    uavs[0].leave()
    assert live_uav_ids(ground, SPACE, 0.1) == [74]


def test_a_token_that_is_no_uav_is_ignored() -> None:
    network = MemoryNetwork()
    network.bus().declare_token(f"{SPACE.prefix}/uav/x/alive")
    MemoryUav(network, 7)
    assert live_uav_ids(network.bus(), SPACE, 0.1) == [7]


def test_the_live_view_follows_tokens_and_status_messages() -> None:
    network = MemoryNetwork()
    statuses: list[StatusRecord] = []
    early = MemoryUav(network, 5)
    with FleetView(network.bus(), SPACE, on_status=statuses.append) as view:
        assert view.live_ids() == [5]  # a token present before the view is seen at once
        late = MemoryUav(network, 6)
        assert view.live_ids() == [5, 6]
        late.bus.publish(SPACE.status(6), StatusText("link slow", StatusKind.WARNING))
        assert [(s.uav, s.text, s.severity) for s in statuses] == [
            (6, "link slow", Severity.WARNING)
        ]
        early.leave()
        assert view.live_ids() == [6]
        view.refresh_states(0.1)
        assert [v.id for v in view.snapshot()] == [6]


def test_a_uav_along_its_queue_shows_the_target_it_flies_to_and_those_it_reached() -> None:
    """UAV 74 queues targets 0 then 2 and has reached 0; its row shows target 2
    (not its queue's first) and 0 among those it reached; a UAV that does not say its
    current target shows its queue's first, as before."""
    from fleet.mission.messages import AssignmentReport, MissionProgress, UavState
    from fleet.mission.phase import Phase
    from ground.fleet_view import view_from_state

    queues = {74: (0, 2), 112: (1,)}
    report = AssignmentReport(7, 74, 0, {74: 0, 112: 1}, (), (74, 112), "d", queues=queues)
    progress = MissionProgress(
        7, Phase.FLYING, 3, assignment=report, current_target=2, reached={0: 74, 1: 112}
    )
    state = UavState(74, True, 1.0, None, None, None, progress)
    view = view_from_state(state)
    assert (view.target, view.reached, view.queue) == (2, (0,), 2)
    older = UavState(
        74, True, 1.0, None, None, None, MissionProgress(7, Phase.FLYING, 3, None, report)
    )
    assert view_from_state(older).target == 0


class Signed(DelegatingBus):
    """The in-memory bus as the secure profile's: a token is no UAV's word, while what
    reaches a subscription or answers a state query is (the Zenoh bus checks that)."""

    def __init__(self, under: Bus) -> None:
        self._under = under

    @property
    def under(self) -> Bus:
        return self._under

    def put(self, key: str, payload: bytes) -> None:
        self._under.put(key, payload)

    def close(self) -> None:
        self._under.close()

    @property
    def signed(self) -> bool:
        return True


def test_in_the_secure_profile_a_token_alone_shows_no_uav() -> None:
    """A ghost UAV 299's token (anyone on the way can declare one) is shown by neither
    `ground-cli uavs` nor the live view until UAV 299 speaks for itself: its signed state
    answers, or its stream (vouched for by its signed digest) is heard. In the open
    profile the token is enough, as before."""
    network = MemoryNetwork()
    ghost = network.bus()
    ghost.declare_token(SPACE.alive(299))
    MemoryUav(network, 74)
    ground = Signed(network.bus())
    assert [v.id for v in fleet_snapshot(ground, SPACE, 0.1)] == [74]
    assert [v.id for v in fleet_snapshot(network.bus(), SPACE, 0.1)] == [74, 299]
    with FleetView(ground, SPACE) as view:
        view.refresh_states(0.1)
        assert view.live_ids() == [74]
        assert [v.id for v in view.snapshot()] == [74]
        ghost.publish(SPACE.status(299), StatusText("here after all", StatusKind.INFO))
        assert view.live_ids() == [74, 299]
    with FleetView(network.bus(), SPACE) as view:
        assert view.live_ids() == [74, 299]
