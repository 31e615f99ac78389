"""A minimal reproduction: two threads compiling the same msgspec Struct types crash.

msgspec 0.22.0, CPython 3.11: each trial defines fresh Struct classes (a telemetry
message with two nested structs, string annotations as under `from __future__ import
annotations`) and starts two threads at once: one makes `msgspec.json.schema` of
them (msgspec compiles the types, running Python to read their annotations), the
other makes a `msgspec.json.Decoder` of them and decodes a message, three times. Each run is a
process of `--trials` trials; a run ends by SIGSEGV in the decoding thread
(`json_decode_struct_map_inner`) when the decoder was built on a class whose decoding
info the other thread had attached but not finished. `locked`: both compile under one
lock (what `fleet.transport.bus_codec.TYPE_INFO_LOCK` does).

    python -m bench.msgspec_compile_race [--runs 4] [--trials 3000]

prints, for `unlocked` and `locked`, how many runs ended cleanly and how many by a signal.
"""

from __future__ import annotations

import argparse
import collections
import signal
import subprocess
import sys

CHILD = '''
import sys, threading, types, msgspec
sys.setswitchinterval(1e-6)
SOURCE = """
from __future__ import annotations
import msgspec
class Gps(msgspec.Struct):
    lat: float
    lon: float
    alt: float
    vel_north: float
    vel_east: float
    vel_down: float
class Sensor(msgspec.Struct):
    roll: float
    pitch: float
    yaw: float
class Telemetry(msgspec.Struct):
    t: int
    gps: Gps | None = None
    sensor: Sensor | None = None
"""
PAYLOAD = (
    b'{"t":1,"gps":{"lat":1.0,"lon":2.0,"alt":3.0,"vel_north":0.0,"vel_east":0.0,'
    b'"vel_down":0.0},"sensor":{"roll":0.0,"pitch":0.0,"yaw":0.0}}'
)
lock = threading.Lock() if sys.argv[2] == "locked" else None
def compiled(make):
    if lock is None:
        return make()
    with lock:
        return make()
for trial in range(int(sys.argv[1])):
    module = types.ModuleType(f"trial{trial}")
    sys.modules[module.__name__] = module
    exec(SOURCE, module.__dict__)
    kind = module.Telemetry
    start = threading.Barrier(2)
    def schema():
        start.wait()
        compiled(lambda: msgspec.json.schema(kind))
    def decode():
        start.wait()
        for _ in range(3):  # the first decoders made while the schema is made
            compiled(lambda: msgspec.json.Decoder(kind)).decode(PAYLOAD)
    threads = [threading.Thread(target=schema), threading.Thread(target=decode)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
'''


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4)
    parser.add_argument("--trials", type=int, default=3000, help="trials per run")
    args = parser.parse_args()
    for variant in ("unlocked", "locked"):
        ends: collections.Counter[str] = collections.Counter()
        for _ in range(args.runs):
            run = subprocess.run(
                [sys.executable, "-c", CHILD, str(args.trials), variant],
                capture_output=True,
                timeout=600,
                check=False,
            )
            code = run.returncode
            ends[
                "clean"
                if code == 0
                else signal.Signals(-code).name
                if code < 0
                else f"status {code}"
            ] += 1
        told = ", ".join(f"{name} {n}" for name, n in ends.most_common())
        print(f"{variant}: {args.runs} runs of {args.trials} trials: {told}", flush=True)


if __name__ == "__main__":
    main()
