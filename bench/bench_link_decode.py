"""Link decoder throughput on a realistic mixed stream, against the 57,600-baud line rate.

Run: .venv/bin/python -m bench.bench_link_decode [--seconds 600] [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

from fleet.payload.link import PiccoloLink
from tests.support.mixed_stream import mixed_stream

LINE_RATE_BYTES_PER_S = 57_600 / 10  # 8N1: ten bits a byte


def decode_all(data: bytes, chunk: int) -> tuple[int, float]:
    link = PiccoloLink(local_address=0)
    events = 0
    start = time.perf_counter()
    for position in range(0, len(data), chunk):
        events += len(link.feed(data[position : position + chunk]))
    return events, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=600.0, help="simulated seconds of link")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    stream = mixed_stream(args.seconds)
    megabytes = len(stream.data) / 1e6
    print(
        f"stream: {megabytes:.2f} MB, {stream.packets} stream packets "
        f"({stream.corrupted} corrupted), {args.seconds:g} s of link at 20 Hz telemetry"
    )
    print(f"{'chunk':>8} {'MB/s':>8} {'packets/s':>11} {'x line rate':>12} {'messages':>9}")
    for chunk in (64, 4096, 65536):
        best = min(decode_all(stream.data, chunk)[1] for _ in range(args.repeat))
        events, _ = decode_all(stream.data, chunk)
        rate = len(stream.data) / best
        print(
            f"{chunk:>8} {rate / 1e6:>8.2f} {stream.packets / best:>11,.0f} "
            f"{rate / LINE_RATE_BYTES_PER_S:>12,.0f} {events:>9}"
        )


if __name__ == "__main__":
    main()
