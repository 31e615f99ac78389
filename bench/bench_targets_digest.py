"""A mission's acknowledgement by content: what the targets digest costs.

Each UAV's state carries `targets_digest` (`fleet.consensus.targets_digest`), computed
once per mission and then looked up at every state report. Measured at MAX_TARGETS
targets and a 50-UAV team, against the reference each state report already pays,
encoding the state with its telemetry (`bus_codec.encode`), in the same run: the first
digest of a mission, and the look-up a state report pays afterwards.

Run: .venv/bin/python -m bench.bench_targets_digest [--repeat 2000]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

from fleet.consensus.targets_digest import targets_digest
from fleet.mission.messages import (
    MAX_TARGETS,
    MissionProgress,
    MissionTargets,
    Target,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.piccolo.telemetry import GpsBlock, SensorBlock, Telemetry
from fleet.transport import bus_codec

TEAM = tuple(range(1, 51))


def per_call_us(call: Callable[[], object], repeat: int) -> float:
    start = time.perf_counter()
    for _ in range(repeat):
        call()
    return (time.perf_counter() - start) / repeat * 1e6


def mission(m: int) -> MissionTargets:
    targets = tuple(Target(35.0 + i * 1e-3, -120.0 - i * 1e-3, 600.0) for i in range(MAX_TARGETS))
    return MissionTargets(m, TEAM, targets)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2000)
    args = parser.parse_args()
    held = mission(1)
    digest = targets_digest(held)
    progress = MissionProgress(1, Phase.FLYING, MAX_TARGETS, targets_digest=digest)
    telemetry = Telemetry(
        system_time_ms=1000,
        gps=GpsBlock(35.0, -120.0, 600.0, vel_north=0.0, vel_east=20.0, vel_down=0.0),
        sensor=SensorBlock(roll=0.0, pitch=0.0, yaw=90.0, indicated_airspeed=21.0),
    )
    state = UavState(7, True, 1.0, 3, telemetry, None, progress, "flying")
    reference = per_call_us(lambda: bus_codec.encode(state), args.repeat)
    fresh = iter(range(2, 2 + args.repeat))
    first = per_call_us(lambda: targets_digest(mission(next(fresh))), args.repeat)
    build = per_call_us(lambda: mission(0), args.repeat)
    targets_digest(held)  # the mission held again, as a UAV holds one
    looked_up = per_call_us(lambda: targets_digest(held), args.repeat)
    print(f"reference: encoding a state report             {reference:8.1f} us")
    print(f"first digest of a {MAX_TARGETS}-target mission        {first - build:8.1f} us "
          f"({(first - build) / reference:.2f}x the reference, once per mission)")  # fmt: skip
    print(f"digest looked up at each state report          {looked_up:8.1f} us "
          f"({looked_up / reference:.2f}x the reference)")  # fmt: skip


if __name__ == "__main__":
    main()
