"""Signed commands: what signing and checking cost per message, and at N=50.

For each message kind that is signed, at the size it has in a 50-UAV mission, the time
to sign it (`BusSigning.attachment`: the envelope) and to check it (`BusSigning.check`:
the author's right to the key, the Ed25519 signature, freshness), against the reference
every bus message already pays, decoding and checking it (`bus_codec.decode`), measured
in the same run. Then what one UAV spends on signatures in one mission round at N=50 and
per second of the teammates' state reports.

Run: .venv/bin/python -m bench.bench_signing [--repeat 2000]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass

import msgspec
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from fleet.mission.access import GROUND, uav_identity
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionProgress,
    MissionTargets,
    OpmCommand,
    Target,
    TargetOutcome,
    UavResult,
    UavState,
)
from fleet.mission.phase import Phase
from fleet.mission.signature import Delivery, Roster
from fleet.transport import bus_codec
from fleet.transport.signing import BusSigning

N = 50
SPACE = KeySpace()
MISSION = 7
UAVS = tuple(range(1, N + 1))


@dataclass(frozen=True)
class Sample:
    name: str
    author: str
    key: str
    message: msgspec.Struct


def samples() -> list[Sample]:
    targets = tuple(Target(35.7 + i / 1000, -120.7 - i / 1000, 600.0) for i in range(N))
    uav = UAVS[0]
    state = UavState(
        uav, True, 1.0, 90, None, None, MissionProgress(MISSION, Phase.FLYING, N), "flying"
    )
    return [
        Sample("targets", GROUND, SPACE.mission_targets(MISSION),
               MissionTargets(MISSION, UAVS, targets)),
        Sample("abort", GROUND, SPACE.mission_abort(MISSION), MissionAbort(MISSION)),
        Sample("opm", GROUND, SPACE.opm(uav), OpmCommand(enabled=False)),
        Sample("result", uav_identity(uav), SPACE.mission_result(MISSION, uav),
               UavResult(MISSION, uav, tuple(100.0 + i for i in range(N)))),
        Sample("assignment", uav_identity(uav), SPACE.mission_assignment(MISSION, uav),
               AssignmentReport(MISSION, uav, 0, {u: u - 1 for u in UAVS}, (), UAVS, "d" * 16)),
        Sample("outcome", uav_identity(uav), SPACE.mission_outcome(MISSION, uav),
               TargetOutcome(MISSION, uav, 0, Phase.REACHED)),
        Sample("state", uav_identity(uav), SPACE.state(uav), state),
    ]  # fmt: skip


def best_per_call(run: Callable[[int], None], repeat: int, rounds: int = 3) -> float:
    """The best of `rounds` runs of `repeat` calls, in microseconds a call."""
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        run(repeat)
        best = min(best, time.perf_counter() - start)
    return best / repeat * 1e6


def measure(sample: Sample, repeat: int) -> tuple[int, float, float, float]:
    """(payload bytes, sign µs, check µs, decode µs) for one sample."""
    key = Ed25519PrivateKey.generate()
    roster = Roster({sample.author: key.public_key()})
    signer = BusSigning(sample.author, key, roster)
    receiver = BusSigning("uav-999", Ed25519PrivateKey.generate(), roster)
    payload = bus_codec.encode(sample.message)
    kind = type(sample.message)

    def sign(count: int) -> None:
        for _ in range(count):
            signer.attachment(sample.key, payload, Delivery.PUT)

    # Each check needs its own envelope: a second check of one would be a replay.
    envelopes = [
        signer.attachment(sample.key, payload, Delivery.PUT) or b"" for _ in range(repeat * 3)
    ]
    position = iter(envelopes)

    def check(count: int) -> None:
        for _ in range(count):
            assert receiver.check(sample.key, payload, next(position), Delivery.PUT)

    def decode(count: int) -> None:
        for _ in range(count):
            bus_codec.decode(payload, kind, sample.key)

    return (
        len(payload),
        best_per_call(sign, repeat),
        best_per_call(check, repeat),
        best_per_call(decode, repeat),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=2000)
    args = parser.parse_args()
    print(f"per message, N={N} (best of 3 x {args.repeat}); reference: bus_codec.decode")
    print(f"{'message':>11} {'bytes':>6} {'sign us':>8} {'check us':>9} {'decode us':>10} "
          f"{'(sign+check)/decode':>20}")  # fmt: skip
    costs: dict[str, tuple[float, float]] = {}
    for sample in samples():
        size, sign_us, check_us, decode_us = measure(sample, args.repeat)
        costs[sample.name] = (sign_us, check_us)
        print(f"{sample.name:>11} {size:>6} {sign_us:>8.1f} {check_us:>9.1f} {decode_us:>10.1f} "
              f"{(sign_us + check_us) / decode_us:>20.1f}")  # fmt: skip
    teammates = N - 1
    # One mission round as one UAV sees it: the targets, each teammate's result,
    # assignment and outcome checked; its own three signed.
    checked = costs["targets"][1] + teammates * sum(
        costs[k][1] for k in ("result", "assignment", "outcome")
    )
    signed = sum(costs[k][0] for k in ("result", "assignment", "outcome"))
    print(f"one UAV, one mission round at N={N}: {checked / 1000:.1f} ms checking "
          f"{1 + 3 * teammates} messages, {signed / 1000:.2f} ms signing 3")  # fmt: skip
    # States at the default 1 Hz: each UAV signs its own, and the ground (which follows
    # every state) checks N a second.
    state_sign, state_check = costs["state"]
    print(f"states at 1 Hz: a UAV signs 1/s ({state_sign / 1e4:.3f} % of a core); the ground "
          f"checks {N}/s ({N * state_check / 1e4:.2f} % of a core)")  # fmt: skip


if __name__ == "__main__":
    main()
