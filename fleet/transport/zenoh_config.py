"""Zenoh session configuration shared by every fleet process.

Multicast scouting is off everywhere: it is slow or broken in containers and CI
(architecture.md), so peers are always named by explicit tcp endpoints. The scouting
delay is 0 so a router-mode session opens in milliseconds rather than 500 ms.
"""

from __future__ import annotations

import json
import os

import zenoh

DEFAULT_ROUTER = "tcp/127.0.0.1:7447"
CONNECT_ENV = "FLEET_ZENOH_CONNECT"
MODES = ("client", "peer", "router")


def default_connect() -> str:
    """The router to connect to: $FLEET_ZENOH_CONNECT, else the local fleet's router."""
    return os.environ.get(CONNECT_ENV, DEFAULT_ROUTER)


def make_config(
    mode: str = "client",
    connect: list[str] | None = None,
    listen: list[str] | None = None,
) -> zenoh.Config:
    if mode not in MODES:
        raise ValueError(f"zenoh mode {mode!r}: expected one of {', '.join(MODES)}")
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/delay", "0")
    if connect:
        config.insert_json5("connect/endpoints", json.dumps(connect))
    if listen:
        config.insert_json5("listen/endpoints", json.dumps(listen))
    if mode == "router":
        # Let stock tools read the router's admin space (`@/**`).
        config.insert_json5("adminspace/enabled", "true")
    return config
