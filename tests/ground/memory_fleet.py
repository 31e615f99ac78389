"""Fake UAVs on the in-memory bus, for the ground's unit tests: each holds its
liveliness token and answers its state query (and, once it flies a mission, that
mission's targets and its result) as each query arrives."""

from __future__ import annotations

from collections.abc import Callable

import msgspec

from fleet.consensus.targets_digest import targets_digest
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionProgress, MissionTargets, UavResult, UavState
from fleet.mission.phase import Phase
from fleet.transport.bus import Queryable
from fleet.transport.memory import MemoryBus, MemoryNetwork

SPACE = KeySpace()


class MemoryUav:
    """A UAV's side of the bus: its token, its state, and what it serves."""

    def __init__(self, network: MemoryNetwork, uav: int) -> None:
        self.uav = uav
        self.bus: MemoryBus = network.bus()
        self.state = UavState(uav, True, 1.0, None, None, None, None)
        self.bus.declare_token(SPACE.alive(uav))
        self._serve(SPACE.state(uav), lambda: self.state)

    def fly(
        self, targets: MissionTargets, result: UavResult | None = None, *, digest: bool = True
    ) -> None:
        """Hold `targets` as the current mission (with `result`), as a UAV that got it;
        `digest`: its state reports the targets' digest (False: an older onboard's)."""
        progress = MissionProgress(
            targets.mission,
            Phase.COMPUTING,
            len(targets.targets),
            result,
            targets_digest=targets_digest(targets) if digest else None,
        )
        self.state = msgspec.structs.replace(self.state, mission=progress, phase=Phase.COMPUTING)
        self._serve(SPACE.mission_targets(targets.mission), lambda: targets)
        if result is not None:
            self._serve(SPACE.mission_result(targets.mission, self.uav), lambda: result)

    def serve(self, key: str, message: msgspec.Struct) -> None:
        """Answer queries on `key` (a concrete key) with `message`."""
        self._serve(key, lambda: message)

    def _serve(self, key: str, value: Callable[[], msgspec.Struct]) -> None:
        def answer() -> None:
            while (query := queryable.try_recv()) is not None:
                query.reply(key, value())
                query.drop()

        queryable: Queryable = self.bus.declare_queryable(key, answer)

    def leave(self) -> None:
        self.bus.close()
