"""Tests of the built-in Zenoh configuration (fleet.transport.zenoh_config)."""

from __future__ import annotations

import json
import threading

import pytest
import zenoh

from fleet.transport.router import Router
from fleet.transport.zenoh_config import MODES, make_config
from tests.support.processes import ANY_PORT


@pytest.mark.parametrize("mode", MODES)
def test_shared_memory_is_off_in_every_mode(mode: str) -> None:
    config = make_config(mode)
    assert json.loads(config.get_json("transport/shared_memory/enabled")) is False
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False


def test_a_message_over_the_shared_memory_threshold_still_arrives() -> None:
    """Zenoh sends messages over 3 KB through shared memory when it is on; off, by TCP."""
    payload = bytes(range(256)) * 40  # 10 KB
    arrived = threading.Event()
    received: list[bytes] = []

    def on_sample(sample: zenoh.Sample) -> None:
        received.append(sample.payload.to_bytes())
        arrived.set()

    with Router([ANY_PORT]) as router:
        subscriber = router.session.declare_subscriber("test/big", on_sample)
        session = zenoh.open(make_config("client", router.endpoints))
        try:
            while not arrived.is_set():  # re-put until the subscription has reached us
                session.put("test/big", payload)
                arrived.wait(0.2)
        finally:
            subscriber.undeclare()
            session.close()
    assert received[0] == payload
