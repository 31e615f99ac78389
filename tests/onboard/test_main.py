"""`onboard`'s command line: what it refuses before starting anything."""

from __future__ import annotations

import pytest

from onboard.core import CONFIRM_LIMIT_S, LINK_RELEASE_S
from onboard.main import build_parser

REQUIRED = ["--id", "112", "--program", "socket://127.0.0.1:1", "--payload", "socket://127.0.0.1:2"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--budget", "-1"], "argument --budget: '-1' must be a positive number"),
        (["--budget", "0"], "argument --budget: '0' must be a positive number"),
        (["--budget", "nan"], "argument --budget: 'nan' is not a finite number"),
        (["--status-rate", "-2"], "argument --status-rate: '-2' must be a number >= 0"),
        (["--id", "0"], "argument --id: the Piccolo ID must be 1-65520, got 0"),
        (["--mode", "sideways"], "argument --mode: invalid choice: 'sideways'"),
        (["--link-release", "0"], "argument --link-release: '0' must be a positive number"),
        (["--confirm-limit", "-1"], "argument --confirm-limit: '-1' must be a positive number"),
    ],
)
def test_bad_arguments_are_refused_with_exit_2(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit, match=r"^2$"):
        build_parser().parse_args([*REQUIRED, *argv])
    assert message in capsys.readouterr().err


def test_defaults() -> None:
    args = build_parser().parse_args(REQUIRED)
    assert args.budget == 2.0 and args.status_rate == 1.0 and args.id == 112
    assert args.connect is None and args.mode is None and args.verbose == 0
    assert (args.confirm_limit, args.link_release) == (CONFIRM_LIMIT_S, LINK_RELEASE_S)
