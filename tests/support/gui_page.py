"""Reaching the Mission Manager's page (`ground-cli gui`) as the page itself does."""

from __future__ import annotations

import re
import urllib.request

from ground.gui.access import SESSION_META

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
