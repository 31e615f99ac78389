"""`fleet`'s root: every subcommand reachable, each module imported only when its command
runs, and a start that costs little CPU."""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from programs.fleet_cli import SUBCOMMANDS, build_parser

REPO = Path(__file__).resolve().parents[2]
#: CPU seconds a `--help` may cost: generous (0.07-0.25 s measured, docs/benchmarks.md),
#: so a loaded box does not fail it, yet far below the 1.05 s it cost before.
HELP_CPU_BOUND_S = 0.8


def _choices(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _helps(parser: argparse.ArgumentParser) -> dict[str, str]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {choice.dest: str(choice.help) for choice in action._choices_actions}


def test_the_root_s_table_names_every_subcommand_with_its_module_s_own_help() -> None:
    full = build_parser()
    assert set(_choices(full)) == set(SUBCOMMANDS)
    assert _helps(full) == {name: help_text for name, (help_text, _) in SUBCOMMANDS.items()}


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_given_its_command_line_only_the_named_command_is_built_in_full(name: str) -> None:
    parser = build_parser(["-v", name])
    choices = _choices(parser)
    assert set(choices) == set(SUBCOMMANDS)
    built = {n for n, sub in choices.items() if sub.add_help}
    module = SUBCOMMANDS[name][1]
    assert name in built
    assert built == {n for n, (_, m) in SUBCOMMANDS.items() if m is module}


def test_no_subcommand_builds_none_and_is_a_usage_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    parser = build_parser(["-v"])
    assert not any(sub.add_help for sub in _choices(parser).values())
    with pytest.raises(SystemExit) as exited:
        parser.parse_args(["-v"])
    assert exited.value.code == 2
    assert "required: command" in capsys.readouterr().err


def _cpu_of(*argv: str) -> float:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(
        [sys.executable, *argv], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert done.returncode == 0, done.stderr
    assert "usage:" in done.stdout
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


@pytest.mark.e2e
def test_help_costs_little_cpu() -> None:
    for root in ("programs.fleet_cli", "ground.cli"):
        # The best of three: a start is not slower than its fastest run, whatever the load.
        cpu = min(_cpu_of("-m", root, "--help") for _ in range(3))
        assert cpu < HELP_CPU_BOUND_S, f"{root} --help used {cpu:.2f} s of CPU"
