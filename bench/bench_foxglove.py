"""Benchmark of `fleet foxglove`'s bridge: what one telemetry costs it to serve.

Run: ``.venv/bin/python -m bench.bench_foxglove`` (about 10 s). In one process, an
in-memory bus carries N telemetry messages of 3 UAVs to the bridge
(`ground.foxglove_live.bridge`), which decodes each, logs it on its channel and logs its
LocationFix; the time runs until the bridge has served the last one. Three cases:

* no client: the channels have no sink (the server with nobody connected);
* a sink: an MCAP writer on the same context (the SDK encodes and writes every message,
  as it does for a subscribed WebSocket client);
* reference: decoding the same payloads alone (`bus_codec.decode_json`), the least any
  consumer of the bus does.

Prints a markdown table: microseconds per telemetry (best of the rounds), the ratio to
the reference, and how many UAVs at 20 Hz of telemetry that is on one core.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import foxglove

from fleet.mission.key_space import KeySpace
from fleet.piccolo.telemetry import GpsBlock, SensorBlock, Telemetry
from fleet.transport import bus_codec
from fleet.transport.memory import MemoryNetwork
from ground.foxglove_live.bridge import QUEUE_LIMIT, FoxgloveBridge

SPACE = KeySpace()
UAVS = (74, 112, 9)
TELEMETRY_HZ = 20.0


def payloads(count: int) -> list[tuple[str, bytes]]:
    found = []
    for i in range(count):
        uav = UAVS[i % len(UAVS)]
        gps = GpsBlock(35.7 + i * 1e-6, -120.7 - i * 1e-6, 600.0 + i % 7, 3.0, 21.5, -0.2)
        sensor = SensorBlock(roll=5.0, pitch=1.5, yaw=(i * 0.1) % 360, indicated_airspeed=22.0)
        telemetry = Telemetry(system_time_ms=i * 50, gps=gps, sensor=sensor, agl=120.0)
        found.append((SPACE.telemetry(uav), bus_codec.encode(telemetry)))
    return found


def bridge_s(messages: list[tuple[str, bytes]], directory: Path | None) -> float:
    """Seconds from the first put until the bridge served the last message."""
    network = MemoryNetwork()
    fleet, ground = network.bus(), network.bus()
    context = foxglove.Context()
    writer = None
    if directory is not None:
        writer = foxglove.open_mcap(directory / "bench.mcap", context=context, allow_overwrite=True)
    bridge = FoxgloveBridge(ground, context, SPACE, state_every_s=0)
    bridge.start()
    try:
        start = time.perf_counter()
        for key, payload in messages:
            fleet.put(key, payload)
        bridge.stop()  # returns once everything queued is served
        elapsed = time.perf_counter() - start
    finally:
        bridge.stop()
        if writer is not None:
            writer.close()
    assert not bridge.dropped, bridge.dropped
    assert sum(bridge.published.values()) == 2 * len(messages)  # telemetry and its fix
    return elapsed


def decode_s(messages: list[tuple[str, bytes]]) -> float:
    start = time.perf_counter()
    for key, payload in messages:
        bus_codec.decode_json(payload, Any, key)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=QUEUE_LIMIT // 2, help="per round")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    messages = payloads(args.count)
    size = sum(len(p) for _, p in messages) / len(messages)
    best: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.rounds):
            cases: dict[str, Callable[[], float]] = {
                "reference: decode only": lambda: decode_s(messages),
                "bridge, no client": lambda: bridge_s(messages, None),
                "bridge, a sink (MCAP)": lambda: bridge_s(messages, Path(tmp)),
            }
            for name, run in cases.items():
                best[name] = min(best.get(name, float("inf")), run())
    reference = best["reference: decode only"]
    print(f"{args.count} telemetry messages of {size:.0f} bytes, best of {args.rounds} rounds")
    print("| case | us per telemetry | x reference | UAVs at 20 Hz on one core |")
    print("|---|---|---|---|")
    for name, seconds in best.items():
        per = seconds / args.count
        print(
            f"| {name} | {per * 1e6:.1f} | {seconds / reference:.1f} | "
            f"{1 / (per * TELEMETRY_HZ):,.0f} |"
        )


if __name__ == "__main__":
    main()
