"""The page's commands: each page id carried out once, all in the order they came."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

from ground.gui.commands import Reply
from ground.gui.ledger import CommandLedger, Later


def test_a_page_id_sent_again_is_answered_with_the_first_reply_not_run_again() -> None:
    async def scenario() -> tuple[list[str], list[Reply], int]:
        ledger = CommandLedger()
        runs: list[str] = []
        release = asyncio.Event()

        async def send() -> Reply:
            runs.append("send")
            await release.wait()  # still running when the page sends it again
            return Reply("p-1", True, "mission 7: sent", mission=7)

        first = ledger.submit("p-1", send)
        await asyncio.sleep(0)
        again = ledger.submit("p-1", send)  # the page reconnected and re-sent it
        release.set()
        replies = [await first, await again]
        later = await ledger.submit("p-1", send)  # and once more, after the reply
        return runs, [*replies, later], ledger.repeats

    runs, replies, repeats = asyncio.run(scenario())
    assert runs == ["send"]
    assert all(reply.message == "mission 7: sent" for reply in replies)
    assert repeats == 2


def test_commands_run_one_at_a_time_in_the_order_they_came() -> None:
    async def scenario() -> list[str]:
        ledger = CommandLedger()
        order: list[str] = []

        def command(name: str, delay_s: float) -> Callable[[], Awaitable[Reply]]:
            async def run() -> Reply:
                order.append(f"{name} start")
                await asyncio.sleep(delay_s)
                order.append(f"{name} end")
                return Reply(name, True, name)

            return run

        slow = ledger.submit("send", command("send", 0.05))
        fast = ledger.submit("abort", command("abort", 0.0))
        await asyncio.gather(slow, fast)
        return order

    assert asyncio.run(scenario()) == ["send start", "send end", "abort start", "abort end"]


def test_an_integer_id_is_a_scripts_and_runs_each_time() -> None:
    async def scenario() -> int:
        ledger = CommandLedger()
        runs = 0

        async def run() -> Reply:
            nonlocal runs
            runs += 1
            return Reply(1, True, "done")

        await ledger.submit(1, run)
        await ledger.submit(1, run)
        return runs

    assert asyncio.run(scenario()) == 2


def test_only_the_latest_outcomes_are_kept() -> None:
    async def scenario() -> int:
        ledger = CommandLedger(kept=3)
        runs = 0

        async def run() -> Reply:
            nonlocal runs
            runs += 1
            return Reply(None, True, "done")

        for name in ("a", "b", "c", "d", "a"):  # "a" was forgotten: run again
            await ledger.submit(name, run)
        return runs

    assert asyncio.run(scenario()) == 5


def test_a_later_reply_is_awaited_after_its_turn_and_holds_up_nothing() -> None:
    """A change put in its turn, its acknowledgements awaited after: an Abort pressed
    meanwhile runs at once, yet after the change was put."""

    async def scenario() -> tuple[list[str], Reply]:
        ledger = CommandLedger()
        order: list[str] = []
        acknowledged = asyncio.Event()

        async def change() -> Reply | Later:
            order.append("change put")

            async def wait() -> Reply:
                await acknowledged.wait()
                order.append("change acknowledged")
                return Reply("p-1", True, "acknowledged")

            return Later(wait)

        async def abort() -> Reply:
            order.append("abort")
            acknowledged.set()
            return Reply("p-2", True, "abort sent")

        first = ledger.submit("p-1", change)
        await ledger.submit("p-2", abort)
        return order, await first

    order, reply = asyncio.run(scenario())
    assert order == ["change put", "abort", "change acknowledged"]
    assert reply.message == "acknowledged"
