"""The page's commands, each carried out once, in the order they came, never in the reader.

A page's socket can drop under load (a browser that answers the server's ping late, a
tab put to sleep); the page then reconnects and sends again every command it has no
reply to. So that a press is never lost nor done twice, the page names each command with
an id of its own (a string unique to that page and press), and the ledger keeps each
such id's outcome: a command seen again is answered with the reply of its first
execution (awaited if it is still running), never executed again. An integer id (a
script's, `ground-cli`-style) is not remembered: such a command is carried out each time.

Execution is serial, in arrival order (an Abort pressed after a Send runs after it), on
tasks of its own, so the socket's reader keeps reading (its pongs too) while a command
waits on the fleet. A command whose effect is done in its turn but whose answer waits
on the fleet (a change in flight, put, then acknowledged by every UAV) returns `Later`:
its wait goes on after its turn, so an Abort pressed meanwhile is not held up by it.
"""

from __future__ import annotations

import asyncio
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from ground.gui.commands import Reply

#: Outcomes kept by id: far more than a page re-sends after a reconnect.
KEPT = 1000


@dataclass(frozen=True)
class Later:
    """A command done in its turn, its reply awaited after it (`wait`)."""

    wait: Callable[[], Awaitable[Reply]]


class CommandLedger:
    """Runs commands one at a time, each page id once. Event-loop only."""

    def __init__(self, kept: int = KEPT) -> None:
        self._kept = kept
        self._outcomes: OrderedDict[str, asyncio.Future[Reply]] = OrderedDict()
        self._turn = asyncio.Lock()  # FIFO: commands run in the order they came
        self.repeats = 0  #: commands answered from an earlier execution

    def submit(
        self, command_id: int | str, run: Callable[[], Awaitable[Reply | Later]]
    ) -> asyncio.Future[Reply]:
        """The reply to the command `command_id`: `run()` in its turn, or, for a page id
        already seen, the first execution's reply."""
        if isinstance(command_id, str):
            known = self._outcomes.get(command_id)
            if known is not None:
                self.repeats += 1
                return known
        outcome: asyncio.Future[Reply] = asyncio.ensure_future(self._in_turn(run))
        if isinstance(command_id, str):
            self._outcomes[command_id] = outcome
            while len(self._outcomes) > self._kept:
                self._outcomes.popitem(last=False)
        return outcome

    async def _in_turn(self, run: Callable[[], Awaitable[Reply | Later]]) -> Reply:
        async with self._turn:
            done = await run()
        if isinstance(done, Later):
            return await done.wait()
        return done

    def pending(self) -> int:
        return sum(1 for outcome in self._outcomes.values() if not outcome.done())
