"""`ground-cli routers`: each secure router and the connections it refused.

Every secure router answers `{prefix}/router/state` (fleet/transport/router.py) with the
links it refused since it started, by kind (docs/security.md); the query keeps every
reply, one per router (a router-per-UAV mesh has several). An open router refuses no
link and does not answer.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from typing import TextIO

from fleet.mission.messages import RouterState
from fleet.transport import bus_codec
from fleet.transport.bus import Bus
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, options_from

log = logging.getLogger(__name__)


def router_states(bus: Bus, key: str, timeout_s: float) -> list[RouterState]:
    """The state of every router that answered `key` within `timeout_s`, by zid."""
    states: dict[str, RouterState] = {}
    for reply in bus.query(key, timeout_s, every_reply=True):
        if not reply.ok:
            continue
        try:
            state = bus_codec.decode(reply.payload, RouterState, reply.key)
        except bus_codec.BadMessage as error:
            log.warning("ignored router state: %s", error)
            continue
        states[state.zid] = state
    return [states[zid] for zid in sorted(states)]


def format_state(state: RouterState) -> str:
    refused = " ".join(f"{kind}={n}" for kind, n in state.refused_links.items()) or "none"
    return f"router {state.zid}: refused links: {refused}"


@dataclass(frozen=True, kw_only=True)
class RoutersOptions(BusOptions):
    json: bool = False


def run_routers(bus: Bus, options: RoutersOptions, out: TextIO) -> int:
    states = router_states(bus, options.key_space.router_state(), options.query_timeout)
    if options.json:
        refused = [{"zid": s.zid, "refused_links": s.refused_links} for s in states]
        print(json.dumps(refused), file=out)
    elif states:
        print("\n".join(format_state(state) for state in states), file=out)
    else:
        print("no secure router answered", file=out)
    return ExitCode.OK


ROUTERS = Command(options_from(RoutersOptions), run_routers)
