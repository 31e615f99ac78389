"""A pytest plugin so that a test run always ends, and says what went wrong.

Why: a test worker that crashed in a native library (a segmentation fault in a Zenoh
callback) was replaced by pytest-xdist, which then ran the crashed test again (with
`--dist loadfile` its whole file's unfinished tests go back in the queue, the crashed
one too) and the run hung near its end for an hour; a crash between tests passed
unnoticed; and a `ground-cli gui` the dead worker had started ran on for 47 minutes.

What it does:

* every test that runs past its time limit (pytest-timeout's: 300 s, e2e 600 s) plus a minute
  has every thread's traceback dumped and its process ended (`faulthandler`'s timer,
  which needs no Python to run: pytest-timeout's signal cannot interrupt a test stuck
  in native code); with xdist that is a crashed worker, reported as below;
* with xdist, a test that crashed its worker is reported failed (by xdist) and is not
  run again (taken off xdist's queue, or skipped if it comes back anyway: a ledger of
  the tests being run, one file each, shared by the workers); the files the dead
  worker had finished are taken off the queue too (xdist 3.8's `--dist loadfile` hung
  on them); and a worker that crashed, in a test or between tests, fails the run;
* each process running tests adopts its orphaned descendants (a child subreaper), so
  that when its tests are done any process they left (even one whose parent died) is
  found: the run fails naming each (PID and command), and they are killed.

Registered by tests/conftest.py; elsewhere `pytest -p tests.support.run_guard`.
"""

from __future__ import annotations

import contextlib
import faulthandler
import hashlib
import os
import shutil
import signal
import tempfile
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from fleet import lifeline
from tests.support.processes import descendants

#: Seconds past a test's time limit before its process is ended from outside Python.
BACKSTOP_S = 60.0
#: The workers' shared ledger of tests being run (a folder), in `workerinput`.
LEDGER = "fleet_crash_ledger"
#: What a worker found left running, in `workeroutput`.
LEFTOVERS = "fleet_leftovers"

_crashes: list[str] = []
_leftovers: list[str] = []


def _is_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


def _is_controller(config: pytest.Config) -> bool:
    """The process that hands tests to xdist workers and runs none itself."""
    return not _is_worker(config) and bool(getattr(config.option, "numprocesses", None))


def pytest_configure(config: pytest.Config) -> None:
    if _is_controller(config):
        config.stash[_ledger_key] = Path(tempfile.mkdtemp(prefix="pytest-ledger-"))
        return
    lifeline.become_subreaper()


_ledger_key = pytest.StashKey[Path]()


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node: Any) -> None:
    node.workerinput[LEDGER] = str(node.config.stash[_ledger_key])


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: object | None) -> None:
    if error is not None:
        _crashes.append(f"worker {node.gateway.id} crashed: {error}")
    _leftovers.extend(getattr(node, "workeroutput", {}).get(LEFTOVERS, ()))


@pytest.hookimpl(optionalhook=True)
def pytest_handlecrashitem(crashitem: str, report: Any, sched: Any) -> None:
    """Keep xdist's file/scope scheduling from running the crashed test again, and from
    hanging: it puts the dead worker's whole work back in its queue, finished files
    included; a finished file handed to the replacement worker is sent as no tests at
    all, no test then ends to make it ask for more, and the run waits forever."""
    workqueue = getattr(sched, "workqueue", None)
    if not isinstance(workqueue, dict):
        return  # the plain load scheduling does not run it again
    for scope, unit in list(workqueue.items()):
        if crashitem in unit:
            unit[crashitem] = True
        if all(unit.values()):
            del workqueue[scope]


def _time_limit(item: pytest.Item) -> float:
    marker = item.get_closest_marker("timeout")
    if marker is not None and marker.args:
        return float(marker.args[0])
    try:
        return float(item.config.getini("timeout") or 0)
    except ValueError:
        return 0.0


def _dump_fd(config: pytest.Config) -> int:
    """The run's real stderr (pytest's own crash-dump descriptor, which its output
    capture does not take), else descriptor 2."""
    with contextlib.suppress(ImportError, KeyError):
        from _pytest.faulthandler import fault_handler_stderr_fd_key

        return config.stash[fault_handler_stderr_fd_key]
    return 2


def _ledger_entry(item: pytest.Item) -> Path | None:
    workerinput = getattr(item.config, "workerinput", None)
    if workerinput is None or LEDGER not in workerinput:
        return None
    name = hashlib.sha256(item.nodeid.encode()).hexdigest()[:32]
    return Path(workerinput[LEDGER]) / name


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item) -> Generator[None, None, None]:
    entry = _ledger_entry(item)
    if entry is not None:
        if entry.exists():
            # It was running when a worker died: xdist reported it failed, and gives
            # it again to the worker that replaced the dead one.
            item.add_marker(pytest.mark.skip(reason="it crashed a worker: not run again"))
        else:
            entry.write_text(item.nodeid)
    limit = _time_limit(item)
    if limit > 0:
        faulthandler.dump_traceback_later(limit + BACKSTOP_S, exit=True, file=_dump_fd(item.config))
    try:
        yield
    finally:
        if limit > 0:
            faulthandler.cancel_dump_traceback_later()
    if entry is not None:
        entry.unlink(missing_ok=True)


def _end_leftovers() -> list[str]:
    """Kill and collect every process still under this one; what each was."""
    left = descendants(os.getpid())
    for pid in left:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    # Collect what this process adopted (and the above): nothing else will.
    with contextlib.suppress(ChildProcessError):
        while os.waitpid(-1, os.WNOHANG)[0] > 0:
            pass
    return [f"PID {pid} ({command})" for pid, command in sorted(left.items())]


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    config = session.config
    if _is_controller(config):
        shutil.rmtree(config.stash[_ledger_key], ignore_errors=True)
    else:
        left = _end_leftovers()
        if _is_worker(config):
            config.workeroutput[LEFTOVERS] = left  # type: ignore[attr-defined]
        else:
            _leftovers.extend(left)
    if (_crashes or _leftovers) and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: Any) -> None:
    if _crashes:
        terminalreporter.write_sep("=", "crashed test workers", red=True)
        for line in _crashes:
            terminalreporter.write_line(line)
    if _leftovers:
        terminalreporter.write_sep("=", "processes the tests left running (killed)", red=True)
        for line in _leftovers:
            terminalreporter.write_line(line)
