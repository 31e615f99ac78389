"""A bus that loses or holds back puts by rule (fleet.transport.faulty_bus)."""

from __future__ import annotations

import queue
import time

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import StatusText
from fleet.transport.bus import BusSample
from fleet.transport.faulty_bus import FaultRule, FaultyBus
from fleet.transport.memory import MemoryNetwork

SPACE = KeySpace()


def listen(network: MemoryNetwork, key_expr: str) -> queue.SimpleQueue[BusSample]:
    heard: queue.SimpleQueue[BusSample] = queue.SimpleQueue()
    network.bus().subscribe(key_expr, heard.put)
    return heard


def drain(heard: queue.SimpleQueue[BusSample]) -> list[tuple[str, bytes]]:
    out = []
    while not heard.empty():
        sample = heard.get()
        out.append((sample.key, sample.payload))
    return out


def test_the_first_puts_on_each_matching_key_are_dropped_and_counted() -> None:
    network = MemoryNetwork()
    heard = listen(network, "fleet/**")
    bus = FaultyBus(network.bus(), FaultRule("fleet/mission/*/result/1", drop_first=1))
    for mission in (1, 2):
        bus.put(f"fleet/mission/{mission}/result/1", b"first")
        bus.put(f"fleet/mission/{mission}/result/1", b"again")
    bus.put("fleet/mission/1/result/2", b"a teammate's")
    assert drain(heard) == [
        ("fleet/mission/1/result/1", b"again"),
        ("fleet/mission/2/result/1", b"again"),
        ("fleet/mission/1/result/2", b"a teammate's"),
    ]
    assert bus.dropped == {"fleet/mission/1/result/1": 1, "fleet/mission/2/result/1": 1}
    assert not bus.delayed


def test_publish_goes_through_the_rules() -> None:
    network = MemoryNetwork()
    heard = listen(network, SPACE.status(7))
    bus = FaultyBus(network.bus(), FaultRule(SPACE.status(7), drop_first=2))
    for n in range(3):
        bus.publish(SPACE.status(7), StatusText(f"status {n}"))
    assert len(drain(heard)) == 1
    assert bus.dropped[SPACE.status(7)] == 2


def test_the_first_matching_rule_decides() -> None:
    network = MemoryNetwork()
    heard = listen(network, "a/**")
    bus = FaultyBus(network.bus(), FaultRule("a/keep"), FaultRule("a/*", drop_first=5))
    bus.put("a/keep", b"1")
    bus.put("a/lose", b"2")
    assert drain(heard) == [("a/keep", b"1")]
    assert dict(bus.dropped) == {"a/lose": 1}


def test_delayed_puts_arrive_late_and_in_order() -> None:
    network = MemoryNetwork()
    heard = listen(network, "a/*")
    bus = FaultyBus(network.bus(), FaultRule("a/late", delay_s=0.2))
    started = time.monotonic()
    bus.put("a/late", b"late")
    bus.put("a/now", b"now")
    assert drain(heard) == [("a/now", b"now")]
    sample = heard.get(timeout=5.0)
    assert (sample.key, sample.payload) == ("a/late", b"late")
    assert time.monotonic() - started >= 0.2
    assert bus.delayed == {"a/late": 1}


def test_closing_loses_what_is_held_back_and_closes_the_wrapped_bus() -> None:
    network = MemoryNetwork()
    heard = listen(network, "a/*")
    inner = network.bus()
    bus = FaultyBus(inner, FaultRule("a/late", delay_s=0.1))
    bus.put("a/late", b"late")
    bus.close()
    time.sleep(0.3)
    assert drain(heard) == []
    assert inner.closed


def test_everything_else_is_the_wrapped_bus() -> None:
    network = MemoryNetwork()
    bus = FaultyBus(network.bus(), FaultRule("**", drop_first=100))
    heard: queue.SimpleQueue[BusSample] = queue.SimpleQueue()
    bus.subscribe("b/*", heard.put)
    network.bus().put("b/1", b"x")
    assert heard.get_nowait() == BusSample("b/1", b"x")
    presence: list[tuple[str, bool]] = []
    bus.subscribe_presence("alive/*", lambda key, alive: presence.append((key, alive)))
    token = network.bus().declare_token("alive/3")
    token.undeclare()
    assert presence == [("alive/3", True), ("alive/3", False)]
    queryable = bus.declare_queryable("q/*")
    replies: list[BusSample] = []
    network.bus().get("q/1", replies.append, timeout=1.0)
    query = queryable.try_recv()
    assert query is not None
    query.reply_bytes("q/1", b"answer")  # replies are not puts: no rule applies
    assert replies == [BusSample("q/1", b"answer")]
