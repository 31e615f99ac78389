"""`ground-cli uavs`, `watch`, `opm` and `keys`: what the fleet is, and one UAV's module."""

from __future__ import annotations

import argparse
import json
import sys
import threading

from fleet.mission.messages import StatusText
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus import BusSample, decode_sample
from fleet.transport.cli import ExitCode
from fleet.transport.zenoh_bus import client_bus
from ground import keyspace
from ground.fleet_view import fleet_snapshot, format_table
from ground.mission_control import send_opm
from ground.watch import watch

#: How long `opm` waits for the UAV's status message confirming the change.
OPM_CONFIRM_S = 2.0
#: The status kinds a UAV answers an OPM command with: applied, or refused.
OPM_ANSWERS = frozenset({StatusKind.MODULE_SET, StatusKind.OPM_REFUSED})


def cmd_uavs(args: argparse.Namespace) -> int:
    with client_bus(args.zenoh) as bus:
        views = fleet_snapshot(bus, args.key_space, args.query_timeout)
    if args.json:
        print(json.dumps([v.to_json() for v in views]))
    elif views:
        print(format_table(views))
    else:
        print("no live UAV")
    return ExitCode.OK


def cmd_watch(args: argparse.Namespace) -> int:
    with client_bus(args.zenoh) as bus:
        watch(
            bus,
            args.key_space,
            sys.stdout,
            count=args.count,
            duration_s=args.duration,
            interval_s=args.interval,
            query_timeout_s=min(args.query_timeout, args.interval),
        )
    return ExitCode.OK


def cmd_opm(args: argparse.Namespace) -> int:
    enabled = args.state == "on"
    space = args.key_space
    with client_bus(args.zenoh) as bus:
        if not bus.live_tokens(space.alive(args.uav), args.query_timeout):
            print(
                f"error: UAV {args.uav} is not live (no {space.alive(args.uav)} token); "
                "nothing sent",
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
        subscription = bus.subscribe(space.status(args.uav), on_status)
        try:
            send_opm(bus, space, args.uav, enabled, args.status_rate)
            print(f"UAV {args.uav}: planning module {args.state} sent")
            if confirmed.wait(OPM_CONFIRM_S):
                print(f"UAV {args.uav}: {answer[0]}")
            else:
                print(f"UAV {args.uav}: no confirmation within {OPM_CONFIRM_S:g} s")
        finally:
            subscription.undeclare()
    return ExitCode.OK


def cmd_keys(args: argparse.Namespace) -> int:
    with client_bus(args.zenoh) as bus:
        values = keyspace.collect(
            bus,
            args.expr or keyspace.default_expr(args.key_space),
            window_s=args.window,
            timeout_s=args.query_timeout,
            admin=args.admin,
        )
    if args.json:
        print(json.dumps([v.to_json() for v in values]))
    else:
        for line in keyspace.format_lines(values, full=args.full):
            print(line)
    return ExitCode.OK
