"""A UAV's streams vouched for by its signed digests, on real Zenoh sessions (a router on
loopback, in this process): every subscription of a bus believes what the UAV streamed,
whichever of them Zenoh calls first, and what the UAV did not stream is never delivered,
by a callback or through a ring."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleet.mission.key_space import KeySpace
from fleet.transport.bus import RingSubscription
from fleet.transport.zenoh_bus import ZenohBus, client_bus
from tests.support.heard import Heard
from tests.support.signed import buses_of, signing_bus
from tests.support.waiting import wait_until

SPACE = KeySpace()
TIMEOUT_S = 10.0


@pytest.fixture
def buses(certs: Path, endpoint: str) -> Iterator[dict[str, ZenohBus]]:
    with buses_of(("ground", "uav-112"), lambda name: signing_bus(certs, endpoint, name)) as made:
        yield made


def taken(ring: RingSubscription, into: Heard) -> Heard:
    while (sample := ring.try_recv()) is not None:
        into(sample)
    return into


def stream_until(uav: ZenohBus, template: bytes, heard: Callable[[], object], what: str) -> int:
    """Put UAV 112's telemetry `template % n` for n = 1, 2, ... until `heard()` is true
    (until the subscriptions have reached the router, a put may go unheard); how many
    were put."""
    sent = 0

    def streamed_and_heard() -> bool:
        nonlocal sent
        sent += 1
        uav.put(SPACE.telemetry(112), template % sent)
        return bool(heard())

    wait_until(streamed_and_heard, TIMEOUT_S, what)
    return sent


def test_every_subscription_believes_what_the_uav_streamed(
    buses: dict[str, ZenohBus],
) -> None:
    """A recorder's `fleet/**` and a telemetry subscription on one bus both hear the
    UAV's digest (and the bus's own digest subscription too): each believes it once, so
    each gets the telemetry; the digest heard by one never makes the other refuse it as
    replayed (which left a Foxglove bridge without any telemetry, in some runs)."""
    ground, uav = buses["ground"], buses["uav-112"]
    everything, telemetry, digests, digests_again = Heard(), Heard(), Heard(), Heard()
    declared = [
        ground.subscribe(SPACE.everything, everything, details=True),
        ground.subscribe(SPACE.all_telemetry, telemetry),
        ground.subscribe(SPACE.all_digests, digests),
        ground.subscribe(SPACE.all_digests, digests_again),
    ]
    try:
        sent = stream_until(
            uav, b'{"n":%d}', lambda: telemetry.payloads, "the first telemetry believed"
        )
        last = b'{"n":%d}' % sent
        wait_until(lambda: last in telemetry and last in everything, TIMEOUT_S, "the last")
        wait_until(lambda: digests.payloads and digests_again.payloads, TIMEOUT_S, "digests")
    finally:
        for declaration in declared:
            declaration.undeclare()


def test_a_ring_delivers_what_the_uav_streamed_and_never_a_forgery(
    buses: dict[str, ZenohBus], endpoint: str
) -> None:
    """The ring (the recorder in a router's process) believes a stream sample as a
    subscription does: once the UAV's signed digest lists it. A sample put on the UAV's
    telemetry key by anyone else (a rogue router or client, which signs no digest of that
    UAV's) is never taken from it, nor from a subscription."""
    ground, uav = buses["ground"], buses["uav-112"]
    ring = ground.subscribe_ring(SPACE.everything, 1000)
    subscribed = Heard()
    subscription = ground.subscribe(SPACE.all_telemetry, subscribed)
    heard = Heard()
    try:
        sent = stream_until(
            uav,
            b'{"genuine":%d}',
            lambda: taken(ring, heard).payloads,
            "the first telemetry taken from the ring",
        )
        with client_bus(endpoint) as rogue:  # no digest of UAV 112's vouches for these
            for n in range(5):
                rogue.put(SPACE.telemetry(112), b'{"forged":%d}' % n)
        uav.put(SPACE.telemetry(112), b'{"genuine":"last"}')
        wait_until(
            lambda: b'{"genuine":"last"}' in taken(ring, heard), TIMEOUT_S, "the last genuine"
        )
        wait_until(lambda: b'{"genuine":"last"}' in subscribed, TIMEOUT_S, "it subscribed")
        forged = [p for p in heard.payloads + subscribed.payloads if b"forged" in p]
        assert forged == []
        # What the ring gave is what the UAV streamed, and its digests (a signed key).
        telemetry = {p for p in heard.payloads if b"genuine" in p}
        assert telemetry <= {b'{"genuine":%d}' % n for n in range(1, sent + 1)} | {
            b'{"genuine":"last"}'
        }
    finally:
        subscription.undeclare()
        ring.undeclare()
