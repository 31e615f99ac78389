"""Ground-side cost at N UAVs: watch frame period and the page's push rate.

N FakeOnboards (tests/support/fake_onboard.py) on an in-process router, each publishing
telemetry at 10 Hz and a status line every 0.5 s; then
  * `ground-cli watch --count F --interval 0.5` (appended output): wall time per frame,
    UAV rows in the last frame;
  * `ground-cli gui --rate 5`: snapshots received by one WebSocket client in 5 s, and
    their size.
Run: .venv/bin/python -m bench.bench_ground_scale 2 50
Bounded: each ground-cli has a timeout and is stopped by PID; every fake and the router
are closed.
"""

from __future__ import annotations

import asyncio
import json
import signal
import subprocess
import sys
import time

import aiohttp

from fleet.transport.router import Router
from tests.support.fake_onboard import FakeOnboard
from tests.support.gui_page import websocket_url
from tests.support.processes import ANY_PORT, end_process

FRAMES = 10


def measure_watch(router: str) -> str:
    started = time.monotonic()
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "ground.cli",
            "--connect",
            router,
            "watch",
            "--count",
            str(FRAMES),
            "--interval",
            "0.5",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    # Startup (imports, session) is included once; subtract the ideal sleeps.
    elapsed = time.monotonic() - started
    last = done.stdout.rsplit("\n-- ", 1)[-1].splitlines()
    rows = sum(
        1 for line in last if line.split() and line.split()[0].isdigit() and len(line.split()) >= 12
    )
    ideal = (FRAMES - 1) * 0.5
    return (
        f"watch: {FRAMES} frames in {elapsed:.2f} s (ideal {ideal:.1f} s + start-up), "
        f"{rows} UAV rows in the last frame"
    )


async def count_snapshots(url: str, seconds: float) -> tuple[int, int]:
    count = size = 0
    async with aiohttp.ClientSession() as http, http.ws_connect(url) as ws:
        await ws.receive(timeout=30)  # the first, full snapshot
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                message = await ws.receive(timeout=left)
            except TimeoutError:
                break
            if (
                message.type == aiohttp.WSMsgType.TEXT
                and json.loads(message.data)["type"] == "snapshot"
            ):
                count += 1
                size = max(size, len(message.data))
    return count, size


def measure_gui(router: str) -> str:
    gui = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ground.cli",
            "--connect",
            router,
            "gui",
            "--listen",
            "127.0.0.1:0",
            "--rate",
            "5",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        assert gui.stdout is not None
        line = gui.stdout.readline()
        url = line.split("serving on ", 1)[1].strip()
        ws = websocket_url(url)  # with the session token the page holds
        time.sleep(2.0)  # let the trails and states fill
        count, size = asyncio.run(count_snapshots(ws, 5.0))
        rate = count / 5
        return (
            f"gui --rate 5: {count} snapshots in 5 s ({rate:.1f}/s), largest {size / 1000:.0f} kB"
        )
    finally:
        end_process(gui, signal.SIGTERM, 10.0)


def main() -> None:
    for n in map(int, sys.argv[1:]):
        with Router([ANY_PORT]) as router:
            endpoint = router.endpoints[0]
            fakes = []
            try:
                for i in range(n):
                    fakes.append(FakeOnboard(endpoint, 101 + i, 35.7 + i * 1e-3, -120.7, 600.0))
                time.sleep(1.0)
                print(f"N={n}: {measure_watch(endpoint)}", flush=True)
                print(f"N={n}: {measure_gui(endpoint)}", flush=True)
            finally:
                for fake in fakes:
                    fake.close()


if __name__ == "__main__":
    main()
