"""A recording's size per aircraft-minute: as written now, and as it was written before.

Run: ``.venv/bin/python -m bench.bench_recording_size [--scenario head_on] [--seconds 120]``

One flight, recorded twice at once: `fleet up SCENARIO --speedup 1 --no-record` flies
the scenario's targets (sent with `ground-cli send-targets`), and two `fleet record`
processes listen to it over the same window:

* `after`: `fleet record` as it is (LZ4 chunks, telemetry at 5 Hz in the file);
* `full`: `fleet record --telemetry-every 0` (every telemetry, LZ4 chunks); its messages,
  rewritten as the previous writer wrote them (MCAP records, unchunked, uncompressed),
  are `before`.

Prints bytes per aircraft-minute (the file's bytes over the UAVs times the minutes
between its first and last message) for each, and before/after.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import time
from importlib.resources import files
from pathlib import Path

from mcap.writer import Writer

from fleet.launch.endpoints import free_port
from fleet.recording.reader import Recording, read_recording
from tests.support.processes import end_process

FLEET = (sys.executable, "-m", "programs.fleet_cli")
READY_S = 120.0


def _wait_for_line(process: subprocess.Popen[str], text: str, timeout_s: float) -> None:
    assert process.stdout is not None
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            raise RuntimeError(f"exited before printing {text!r}")
        if text in line:
            return
    raise RuntimeError(f"no {text!r} within {timeout_s} s")


def rewrite_unchunked(recording: Recording, out: Path) -> None:
    """The messages as the previous writer wrote them: records, no chunks, no compression."""
    with open(out, "wb") as stream:
        writer = Writer(stream, use_chunking=False)
        writer.start(profile="", library="bench")
        ids: dict[str, int] = {}
        for message in recording.messages:
            channel = ids.get(message.topic)
            if channel is None:
                spec = recording.channels[message.topic]
                schema = writer.register_schema(spec.schema_name, spec.schema_encoding, spec.schema)
                channel = ids[message.topic] = writer.register_channel(
                    message.topic, spec.message_encoding, schema, {"pattern": spec.pattern}
                )
            writer.add_message(channel, message.log_time_ns, message.data, message.publish_time_ns)
        writer.finish()  # type: ignore[no-untyped-call]


def per_aircraft_minute(path: Path, recording: Recording, uavs: int) -> tuple[float, float]:
    """(bytes per aircraft-minute, minutes recorded)."""
    minutes = (recording.messages[-1].log_time_ns - recording.messages[0].log_time_ns) / 60e9
    return path.stat().st_size / (uavs * minutes), minutes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scenario", default="head_on")
    parser.add_argument("--seconds", type=float, default=120.0, help="recorded flight")
    args = parser.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        up = subprocess.Popen(
            [*FLEET, "up", args.scenario, "--listen", endpoint, "--speedup", "1",
             "--no-record", "--log-dir", str(directory / "run")],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )  # fmt: skip
        recorders: list[subprocess.Popen[str]] = []
        try:
            _wait_for_line(up, "stops the fleet", READY_S)
            for name, extra in (("after", ()), ("full", ("--telemetry-every", "0"))):
                recorder = subprocess.Popen(
                    [*FLEET, "record", str(directory / f"{name}.mcap"), "--connect", endpoint,
                     *extra],
                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                )  # fmt: skip
                recorders.append(recorder)
                _wait_for_line(recorder, "fleet record: recording", READY_S)
            targets = files("fleet") / "scenarios" / f"{args.scenario}_targets.bin"
            subprocess.run(
                [sys.executable, "-m", "ground.cli", "--connect", endpoint, "send-targets",
                 str(targets)],
                check=True, capture_output=True, timeout=READY_S,
            )  # fmt: skip
            time.sleep(args.seconds)  # the flight being recorded: a duration, not a wait
        finally:
            for process in (*recorders, up):
                end_process(process, signal.SIGINT, 60.0)
        after = read_recording(directory / "after.mcap")
        full = read_recording(directory / "full.mcap")
        uavs = len({m.topic.split("/")[2] for m in full.messages if m.topic.endswith("/telemetry")})
        rewrite_unchunked(full, directory / "before.mcap")
        before = read_recording(directory / "before.mcap")
        rows = [
            ("before (unchunked, every telemetry)", directory / "before.mcap", before),
            ("LZ4 chunks, every telemetry", directory / "full.mcap", full),
            ("after (LZ4 chunks, telemetry at 5 Hz)", directory / "after.mcap", after),
        ]
        print(f"{args.scenario}: {uavs} UAVs, speedup 1")
        print("| file | messages | bytes | minutes | bytes per aircraft-minute |")
        print("|---|---:|---:|---:|---:|")
        figures = {}
        for name, path, recording in rows:
            rate, minutes = per_aircraft_minute(path, recording, uavs)
            figures[name] = rate
            print(
                f"| {name} | {len(recording.messages):,} | {path.stat().st_size:,} | "
                f"{minutes:.2f} | {rate:,.0f} |"
            )
        ratio = figures[rows[0][0]] / figures[rows[2][0]]
        print(f"before/after: {ratio:.1f}x smaller")


if __name__ == "__main__":
    main()
