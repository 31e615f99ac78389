"""`ground-cli uavs`, `watch`, `opm` and `keys`: what the fleet is, and one UAV's module."""

from __future__ import annotations

import argparse
import json
import sys
import threading
from dataclasses import dataclass
from typing import Literal, TextIO

from fleet.mission.messages import StatusText
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus import Bus, BusSample, decode_sample
from fleet.transport.cli import ExitCode
from fleet.transport.command import BusOptions, Command, fields_from, key_expr_option, options_from
from ground import keyspace
from ground.fleet_view import fleet_snapshot, format_table
from ground.mission_control import send_opm
from ground.watch import watch

#: How long `opm` waits for the UAV's status message confirming the change.
OPM_CONFIRM_S = 2.0
#: The status kinds a UAV answers an OPM command with: applied, or refused.
OPM_ANSWERS = frozenset({StatusKind.MODULE_SET, StatusKind.OPM_REFUSED})


@dataclass(frozen=True, kw_only=True)
class UavsOptions(BusOptions):
    json: bool = False


def run_uavs(bus: Bus, options: UavsOptions, out: TextIO) -> int:
    views = fleet_snapshot(bus, options.key_space, options.query_timeout)
    if options.json:
        print(json.dumps([v.to_json() for v in views]), file=out)
    elif views:
        print(format_table(views), file=out)
    else:
        print("no live UAV", file=out)
    return ExitCode.OK


@dataclass(frozen=True, kw_only=True)
class WatchOptions(BusOptions):
    count: int | None = None
    duration: float | None = None
    interval: float = 1.0


def run_watch(bus: Bus, options: WatchOptions, out: TextIO) -> int:
    watch(
        bus,
        options.key_space,
        out,
        count=options.count,
        duration_s=options.duration,
        interval_s=options.interval,
        query_timeout_s=min(options.query_timeout, options.interval),
    )
    return ExitCode.OK


@dataclass(frozen=True, kw_only=True)
class OpmOptions(BusOptions):
    uav: int
    state: Literal["on", "off"]
    status_rate: float = 1.0


def run_opm(bus: Bus, options: OpmOptions, out: TextIO) -> int:
    enabled = options.state == "on"
    space = options.key_space
    uav = options.uav
    if not bus.live_tokens(space.alive(uav), options.query_timeout):
        print(
            f"error: UAV {uav} is not live (no {space.alive(uav)} token); nothing sent",
            file=sys.stderr,
        )
        return ExitCode.FAILED
    confirmed = threading.Event()
    answer: list[str] = []

    def on_status(sample: BusSample) -> None:
        status = decode_sample(sample, StatusText)
        if status is not None and status.kind in OPM_ANSWERS:
            answer.append(status.text)
            confirmed.set()

    # Listen before sending: the UAV answers with a status message at once.
    subscription = bus.subscribe(space.status(uav), on_status)
    try:
        send_opm(bus, space, uav, enabled, options.status_rate)
        print(f"UAV {uav}: planning module {options.state} sent", file=out)
        if confirmed.wait(OPM_CONFIRM_S):
            print(f"UAV {uav}: {answer[0]}", file=out)
        else:
            print(f"UAV {uav}: no confirmation within {OPM_CONFIRM_S:g} s", file=out)
    finally:
        subscription.undeclare()
    return ExitCode.OK


@dataclass(frozen=True, kw_only=True)
class KeysOptions(BusOptions):
    expr: str | None = None
    admin: bool = False
    window: float = 1.0
    full: bool = False
    json: bool = False


def keys_options(args: argparse.Namespace) -> KeysOptions:
    """`keys`' options; a usage error if EXPR is not a key expression."""
    return fields_from(KeysOptions, args, expr=key_expr_option(args.expr))


def run_keys(bus: Bus, options: KeysOptions, out: TextIO) -> int:
    values = keyspace.collect(
        bus,
        options.expr or keyspace.default_expr(options.key_space),
        window_s=options.window,
        timeout_s=options.query_timeout,
        admin=options.admin,
    )
    if options.json:
        print(json.dumps([v.to_json() for v in values]), file=out)
    else:
        for line in keyspace.format_lines(values, full=options.full):
            print(line, file=out)
    return ExitCode.OK


UAVS = Command(options_from(UavsOptions), run_uavs)
WATCH = Command(options_from(WatchOptions), run_watch)
OPM = Command(options_from(OpmOptions), run_opm)
KEYS = Command(keys_options, run_keys)
