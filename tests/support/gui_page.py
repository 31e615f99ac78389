"""Reaching the Mission Manager's page (`ground-cli gui`) as the page itself does, and
serving it in the test's process (`serving`)."""

from __future__ import annotations

import asyncio
import queue
import re
import threading
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager

from fleet.mission.key_space import DEFAULT_SPACE
from fleet.transport.bus import Bus
from ground.gui.access import SESSION_META
from ground.gui.server import GuiConfig, serve

#: How long the page may take to listen.
READY_S = 30.0

_SESSION = re.compile(rf'<meta name="{SESSION_META}" content="([^"]+)">')


def websocket_url(page: str) -> str:
    """The page's WebSocket (ws://) with the session token only the page it serves
    holds: read from that page, as its script does."""
    page = page.split("?", 1)[0].rstrip("/")
    with urllib.request.urlopen(f"{page}/", timeout=10) as response:
        html = response.read().decode()
    session = _SESSION.search(html)
    if session is None:
        raise AssertionError(f"{page}/ has no session token: {html[:300]}")
    return f"{page.replace('http://', 'ws://', 1)}/ws?session={session[1]}"


@contextmanager
def serving(bus: Bus, token: str | None = None) -> Iterator[str]:
    """The page on `bus`, served by this process on a loopback port the OS picks, from a
    thread of its own (its event loop); yields its URL (no trailing slash), once it
    listens. Stopped on exit as Ctrl-C stops `ground-cli gui`: its task cancelled."""
    config = GuiConfig("127.0.0.1", 0, token, 5.0, 1.0, DEFAULT_SPACE)
    loop = asyncio.new_event_loop()
    ready: queue.Queue[str] = queue.Queue()
    task = loop.create_task(serve(bus, config, ready.put))

    def run() -> None:
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(task)
        except asyncio.CancelledError:
            pass
        finally:
            loop.close()

    thread = threading.Thread(target=run, name="gui", daemon=True)
    thread.start()
    try:
        yield ready.get(timeout=READY_S).rstrip("/")
    finally:
        loop.call_soon_threadsafe(task.cancel)
        thread.join(READY_S)
    assert not thread.is_alive(), "the page's server did not stop"
