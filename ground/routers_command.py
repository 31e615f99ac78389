"""`ground-cli routers`: each secure router and the connections it refused.

Every secure router answers `{prefix}/router/state` (fleet/transport/router.py) with the
links it refused since it started, by kind (docs/security.md); the query keeps every
reply, one per router (a router-per-UAV mesh has several). An open router refuses no
link and does not answer.

Each answer is signed by the router that gives it (its own identity: `router`,
`router-N`), checked by the bus, and shown as that identity's word about itself: a UAV's
router that answers with another router's zid is shown as itself. The query carries a
random challenge the answer must repeat, so an earlier signed answer cannot be replayed.
"""

from __future__ import annotations

import json
import logging
import secrets
from dataclasses import dataclass
from typing import TextIO

from fleet.mission.messages import RouterState
from fleet.transport import bus_codec
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, options_from

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Answer:
    """One router's state, and the identity that signed it (None: unsigned, an open
    fleet's or one made before signing keys)."""

    state: RouterState
    identity: str | None

    def to_json(self) -> dict[str, object]:
        state = self.state
        return {"identity": self.identity, "zid": state.zid, "refused_links": state.refused_links}


def router_states(bus: Bus, key: str, timeout_s: float) -> list[Answer]:
    """The state of every router that answered `key` within `timeout_s`, one per signing
    identity and zid: each signed answer is believed for its signer only."""
    challenge = secrets.token_hex(16)
    states: dict[tuple[str, str], Answer] = {}
    for reply in bus.query(key, timeout_s, challenge.encode(), every_reply=True):
        if not reply.ok:
            continue
        try:
            state = bus_codec.decode(reply.payload, RouterState, reply.key)
        except bus_codec.BadMessage as error:
            log.warning("ignored router state: %s", error)
            continue
        if reply.author is not None and state.challenge != challenge:
            log.warning("ignored %s's router state: not an answer to this query", reply.author)
            continue
        states[(reply.author or "", state.zid)] = Answer(state, reply.author)
    return [states[found] for found in sorted(states)]


def format_state(answer: Answer) -> str:
    state = answer.state
    refused = " ".join(f"{kind}={n}" for kind, n in state.refused_links.items()) or "none"
    who = f"{answer.identity} ({state.zid})" if answer.identity else state.zid
    return f"router {who}: refused links: {refused}"


@dataclass(frozen=True, kw_only=True)
class RoutersOptions(BusOptions):
    json: bool = False


def run_routers(bus: Bus, options: RoutersOptions, out: TextIO) -> int:
    states = router_states(bus, options.key_space.router_state(), options.query_timeout)
    if options.json:
        print(json.dumps([answer.to_json() for answer in states]), file=out)
    elif states:
        print("\n".join(format_state(state) for state in states), file=out)
    else:
        print("no secure router answered", file=out)
    return ExitCode.OK


ROUTERS = Command(options_from(RoutersOptions), run_routers)
