"""`onboard`: the onboard planning module of one UAV."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from types import FrameType

import zenoh

from fleet.transport.zenoh_config import DEFAULT_ROUTER, MODES, default_connect, make_config
from onboard.process import OnboardProcess, OnboardSettings

log = logging.getLogger("onboard")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="onboard", description=__doc__)
    parser.add_argument("--id", type=int, required=True, help="Piccolo ID of this aircraft")
    parser.add_argument("--program", required=True, help="program port: a pyserial URL or path")
    parser.add_argument("--payload", required=True, help="payload port: a pyserial URL or path")
    parser.add_argument("--baud", type=int, default=57_600)
    parser.add_argument(
        "--connect",
        action="append",
        help=f"zenoh endpoint to connect to (default $FLEET_ZENOH_CONNECT or {DEFAULT_ROUTER})",
    )
    parser.add_argument("--listen", action="append", help="zenoh endpoint to listen on")
    parser.add_argument("--mode", choices=MODES, default="client", help="zenoh session mode")
    parser.add_argument(
        "--payload-ground",
        action="store_true",
        help="also send status and results to the ground over the payload port",
    )
    parser.add_argument("--status-rate", type=float, default=1.0, help="status messages a second")
    parser.add_argument("--budget", type=float, default=2.0, help="planning time budget, s")
    parser.add_argument("--drop-first-result", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("-v", "--verbose", action="store_true")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format=f"%(asctime)s onboard[{args.id}] %(name)s %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    if not 1 <= args.id <= 0xFFF0:
        print(f"onboard: Piccolo ID {args.id} outside 1-65520", file=sys.stderr)
        return 2
    connect = args.connect or ([] if args.mode != "client" else [default_connect()])
    config = make_config(args.mode, connect=connect, listen=args.listen)
    settings = OnboardSettings(
        uav_id=args.id,
        program_url=args.program,
        payload_url=args.payload,
        zenoh_config=config,
        baud=args.baud,
        payload_ground=args.payload_ground,
        status_rate_hz=args.status_rate,
        planning_budget_s=args.budget,
        drop_first_result=args.drop_first_result,
    )
    try:
        process = OnboardProcess(settings)
    except zenoh.ZError as error:
        print(f"onboard: cannot join zenoh at {', '.join(connect)}: {error}", file=sys.stderr)
        return 2

    def request_stop(signum: int, frame: FrameType | None) -> None:
        log.info("signal %d: stopping", signum)
        process.stop_requested.set()

    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    process.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
