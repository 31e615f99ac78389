"""`Bus.query`, `Bus.query_messages` and `Bus.live_tokens` on both backends: the
in-memory bus, and a ZenohBus pair on a router on loopback."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from fleet.mission.messages import StatusText
from fleet.transport import bus_codec
from fleet.transport.bus import Bus, BusReply, BusSample
from fleet.transport.memory import MemoryNetwork
from fleet.transport.zenoh_bus import BusConnectError, client_bus, connect
from tests.support.processes import refused_endpoint
from tests.support.waiting import wait_until

TIMEOUT_S = 2.0


@pytest.fixture(params=["memory", "zenoh"])
def pair(request: pytest.FixtureRequest) -> Iterator[tuple[Bus, Bus]]:
    """Two participants of one bus: (asker, answerer)."""
    if request.param == "memory":
        network = MemoryNetwork()
        buses = (network.bus(), network.bus())
        yield buses
        for bus in buses:
            bus.close()
        return
    where = request.getfixturevalue("endpoint")
    with client_bus(where) as asker, client_bus(where) as answerer:
        yield asker, answerer


def serve(bus: Bus, key_expr: str, answer: str | None, error: str | None = None) -> None:
    """Answer every query on `key_expr` as it arrives: `answer` on `key_expr`, `error`."""
    queryable = bus.declare_queryable(key_expr, lambda: drain())
    payloads: list[bytes] = []

    def drain() -> None:
        while (query := queryable.try_recv()) is not None:
            payloads.append(query.payload)
            if answer is not None:
                query.reply(key_expr, StatusText(answer))
            if error is not None:
                query.reply_err(error)
            query.drop()


def wait_answered(bus: Bus, selector: str) -> list[BusReply]:
    """Ask until the answerer's queryable is heard (declarations reach a router late)."""
    found: list[BusReply] = []

    def heard() -> bool:
        found[:] = bus.query(selector, TIMEOUT_S)
        return bool(found)

    wait_until(heard, 10.0, f"an answer on {selector}")
    return found


def test_a_query_returns_each_reply_with_its_key_and_errors_too(pair: tuple[Bus, Bus]) -> None:
    asker, answerer = pair
    serve(answerer, "fleet/uav/1/state", "one")
    serve(answerer, "fleet/uav/2/state", None, error="no state yet")
    replies = wait_answered(asker, "fleet/uav/*/state")
    if len(replies) < 2:  # the second queryable may be heard a moment after the first
        replies = asker.query("fleet/uav/*/state", TIMEOUT_S)
    ok = [r for r in replies if r.ok]
    errors = [r for r in replies if not r.ok]
    assert [(r.key, r.encoding) for r in ok] == [("fleet/uav/1/state", "application/json")]
    assert bus_codec.decode(ok[0].payload, StatusText, ok[0].key) == StatusText("one")
    assert [e.payload for e in errors] == [b"no state yet"]
    # query_messages keeps the decoded successes only.
    assert asker.query_messages("fleet/uav/*/state", StatusText, TIMEOUT_S) == [
        ("fleet/uav/1/state", StatusText("one"))
    ]


def test_every_reply_keeps_two_answers_on_one_key(pair: tuple[Bus, Bus]) -> None:
    asker, answerer = pair
    serve(answerer, "fleet/mission/3/targets", "first")
    serve(answerer, "fleet/mission/3/targets", "second")
    wait_answered(asker, "fleet/mission/3/targets")

    def both() -> bool:
        replies = asker.query("fleet/mission/3/targets", TIMEOUT_S, b"mine", every_reply=True)
        return len(replies) == 2

    wait_until(both, 10.0, "both replies")
    # Without every_reply the replies on one key are consolidated into one.
    assert len(asker.query("fleet/mission/3/targets", TIMEOUT_S)) == 1


def test_the_query_payload_reaches_the_queryable(pair: tuple[Bus, Bus]) -> None:
    asker, answerer = pair
    got: list[bytes] = []
    queryable = answerer.declare_queryable("fleet/x", lambda: take())

    def take() -> None:
        while (query := queryable.try_recv()) is not None:
            got.append(query.payload)
            query.reply_bytes("fleet/x", b"{}")
            query.drop()

    wait_until(lambda: bool(asker.query("fleet/x", TIMEOUT_S, b"candidate")), 10.0, "a reply")
    assert got[-1] == b"candidate"


def test_live_tokens_are_the_tokens_present_now(pair: tuple[Bus, Bus]) -> None:
    asker, answerer = pair
    token = answerer.declare_token("fleet/uav/7/alive")
    answerer.declare_token("fleet/other/alive")
    wait_until(
        lambda: asker.live_tokens("fleet/uav/*/alive", TIMEOUT_S) == ["fleet/uav/7/alive"],
        10.0,
        "the token",
    )
    token.undeclare()
    wait_until(lambda: not asker.live_tokens("fleet/uav/*/alive", TIMEOUT_S), 10.0, "no token")


def test_a_subscription_sees_the_encoding_and_deletes_with_details_only(endpoint: str) -> None:
    with client_bus(endpoint) as listener, client_bus(endpoint) as talker:
        seen: list[BusSample] = []
        plain: list[BusSample] = []
        got = threading.Event()

        def on_sample(sample: BusSample) -> None:
            seen.append(sample)
            got.set()

        listener.subscribe("fleet/k", on_sample, details=True)
        listener.subscribe("fleet/k", plain.append)

        def heard() -> bool:
            talker.session.put("fleet/k", b"hi", encoding="text/plain")
            return got.wait(0.2)

        wait_until(heard, 10.0, "the put")
        assert seen[0] == BusSample("fleet/k", b"hi", "text/plain", deleted=False)
        talker.session.delete("fleet/k")
        wait_until(lambda: any(s.deleted for s in seen), 10.0, "the delete")
        # Without details: key and payload, the encoding and kind never read.
        wait_until(lambda: len(plain) >= len(seen), 10.0, "the plain subscription")
        assert plain[0] == BusSample("fleet/k", b"hi", "application/json", deleted=False)
        assert not any(s.deleted for s in plain) and plain[-1].payload == b""


def test_a_memory_query_nobody_answers_waits_at_most_its_timeout() -> None:
    network = MemoryNetwork()
    asker, silent = network.bus(), network.bus()
    silent.declare_queryable("fleet/q")  # polled by nobody
    assert asker.query("fleet/q", 0.05) == []


def test_connecting_where_no_router_answers_fails_fast_and_says_so() -> None:
    with (
        refused_endpoint() as where,
        pytest.raises(BusConnectError, match=f"no Zenoh router answers at {where}"),
    ):
        connect(where, open_timeout_s=0.5)
    with pytest.raises(BusConnectError):
        connect("not an endpoint")
