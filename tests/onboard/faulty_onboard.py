"""Test-only: the `onboard` process on a bus that loses the first publication of each of
its own mission results (fleet.transport.faulty_bus), so a test can see its teammates
recover them by query. Takes `onboard`'s arguments:
`python -m tests.onboard.faulty_onboard --id 1 --program URL --payload URL --connect ...`.
"""

from __future__ import annotations

import sys

from fleet.mission.key_space import KeySpace
from fleet.transport.cli import ExitCode, setup_logging, stop_on_signals, zenoh_config
from fleet.transport.faulty_bus import FaultRule, FaultyBus
from fleet.transport.zenoh_bus import ZenohBus
from onboard.main import build_parser, settings_from
from onboard.process import OnboardProcess

SPACE = KeySpace()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    setup_logging(args.verbose, name=f"onboard[{args.id}]")
    config = zenoh_config(args)
    own_results = FaultRule(f"{SPACE.prefix}/mission/*/result/{args.id}", drop_first=1)
    bus = FaultyBus(ZenohBus.open(config), own_results)
    process = OnboardProcess(settings_from(args, config), bus=bus)
    with stop_on_signals(process.stop_requested.set):
        process.run()
    return ExitCode.OK


if __name__ == "__main__":
    sys.exit(main())
