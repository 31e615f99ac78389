"""Who may use the page's server: a Host allow-list and a session token.

DNS rebinding: a site the operator visits (`evil.example`) points its name at this
machine's address; its scripts then reach the page's server as the same origin
(`http://evil.example:8321`), and an Origin-equals-Host check passes. Two checks stop it:

* the Host a request names must be the address the server is bound to, or `localhost`
  (a rebinding page's requests name the attacker's host). A server bound to every
  interface (`0.0.0.0`, `::`) cannot know its names: it relies on its token
  (`--allow-remote` requires one);
* a WebSocket, which carries the commands, must present the session token: random per
  run, handed only inside the page the server serves (a meta tag, and a SameSite=Strict
  cookie for this host), which a rebinding page cannot read (its GET of the page is
  refused by the Host check) and whose cookie its browser never sends to another site.

Each refusal is counted and logged (`RefusalLog`: at most a line every few seconds, with
the number refused meanwhile, so a flood cannot fill the log).
"""

from __future__ import annotations

import hmac
import logging
import secrets

from aiohttp import web

from fleet.transport.refusal_log import RefusalLog
from ground.host_check import HostAllowList

log = logging.getLogger(__name__)

SESSION_META = "fleet-session"


class Access:
    """The server's Host allow-list and session token, and what it refused."""

    def __init__(self, bound_host: str) -> None:
        self._hosts = HostAllowList(bound_host)
        self.any_host = self._hosts.any_host
        self.allowed_hosts = self._hosts.hosts
        self.session = secrets.token_urlsafe(32)
        self.refused = 0
        self._refusals = RefusalLog(log)

    def host_allowed(self, host: str | None) -> bool:
        return self._hosts.allowed(host)

    def session_matches(self, given: str) -> bool:
        return hmac.compare_digest(given.encode(), self.session.encode())

    def with_session(self, html: str) -> str:
        """The page's HTML with this run's session token in a meta tag its script reads."""
        meta = f'<meta name="{SESSION_META}" content="{self.session}">'
        return html.replace("<head>", f"<head>\n{meta}", 1)

    def refuse(self, request: web.Request, status: int, reason: str) -> web.Response:
        """Count and (rate-limited) log a refused request; the answer to send."""
        self.refused += 1
        self._refusals.warn(
            f"refused {request.method} {request.path} from {request.remote}: {reason} "
            f"({self.refused} in all)"
        )
        return web.json_response({"error": reason}, status=status)
