"""A UAV's streams vouched for by its signed digests: a sample is delivered once its
author's digest lists it, never otherwise, and once only."""

from __future__ import annotations

import threading
from collections.abc import Callable

from fleet.mission.messages import StreamDigest
from fleet.transport.stream_auth import StreamChecker, StreamSigner, sample_hash

KEY = "fleet/uav/112/telemetry"


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_sample_is_believed_once_its_authors_digest_lists_it() -> None:
    clock = Clock()
    checker = StreamChecker(clock, hold_s=3.0)
    delivered: list[bytes] = []
    checker.hold("uav-112", KEY, b"a", lambda: delivered.append(b"a"))
    checker.hold("uav-112", KEY, b"b", lambda: delivered.append(b"b"))
    assert delivered == []
    # Another author's digest vouches for nothing of 112's.
    checker.vouch("uav-74", StreamDigest(74, [sample_hash(KEY, b"a")]))
    assert delivered == []
    checker.vouch("uav-112", StreamDigest(112, [sample_hash(KEY, b"a"), sample_hash(KEY, b"c")]))
    assert delivered == [b"a"]
    # A sample after its digest is delivered at once, and its hash is used up.
    checker.hold("uav-112", KEY, b"c", lambda: delivered.append(b"c"))
    checker.hold("uav-112", KEY, b"c", lambda: delivered.append(b"c again"))
    assert delivered == [b"a", b"c"]
    # What no digest vouched for in time is dropped and counted.
    clock.now = 10.0
    checker.vouch("uav-112", StreamDigest(112, [sample_hash(KEY, b"b")]))
    assert delivered == [b"a", b"c"] and checker.unverified == 2


def test_each_receiver_is_owed_the_sample_once() -> None:
    """One sample reaches every subscription of a bus it matches: a digest's hash lets
    each of them have it once, held before the digest or heard after it."""
    checker = StreamChecker(Clock(), hold_s=3.0)
    delivered: list[tuple[int, bytes]] = []
    checker.hold("uav-112", KEY, b"a", lambda: delivered.append((1, b"a")), receiver=1)
    checker.hold("uav-112", KEY, b"a", lambda: delivered.append((2, b"a")), receiver=2)
    checker.vouch("uav-112", StreamDigest(112, [sample_hash(KEY, b"a"), sample_hash(KEY, b"b")]))
    assert delivered == [(1, b"a"), (2, b"a")]

    def deliver(receiver: int) -> Callable[[], None]:
        return lambda: delivered.append((receiver, b"b"))

    for receiver in (1, 2, 2):
        checker.hold("uav-112", KEY, b"b", deliver(receiver), receiver)
    assert delivered[2:] == [(1, b"b"), (2, b"b")]  # receiver 2's second copy: a replay
    # The same bytes streamed again, listed by a later digest: owed once more to each.
    checker.vouch("uav-112", StreamDigest(112, [sample_hash(KEY, b"b")]))
    assert delivered[4:] == [(2, b"b")]
    checker.hold("uav-112", KEY, b"b", lambda: delivered.append((1, b"b")), receiver=1)
    assert delivered[5:] == [(1, b"b")]


def test_the_signer_puts_one_digest_of_what_was_streamed() -> None:
    put: list[tuple[str, StreamDigest]] = []
    done = threading.Event()

    def put_digest(key: str, digest: StreamDigest) -> None:
        put.append((key, digest))
        done.set()

    signer = StreamSigner(put_digest, every_s=0.05)
    signer.streamed("fleet/uav/112/digest", 112, KEY, b"a")
    signer.streamed("fleet/uav/112/digest", 112, KEY, b"b")
    assert done.wait(5.0)
    signer.close()
    assert put == [
        (
            "fleet/uav/112/digest",
            StreamDigest(112, [sample_hash(KEY, b"a"), sample_hash(KEY, b"b")]),
        )
    ]
