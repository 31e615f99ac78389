"""A test run always ends (tests.support.run_guard): a test that crashes its worker
fails the run once, without being run again or hanging it; a process left running
fails it too, named."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.e2e

REPO = Path(__file__).resolve().parents[1]
#: Generous: four small pytest processes on a loaded machine.
RUN_S = 600.0

CRASHING = """
import os

def test_before():
    pass

def test_crash():
    os.abort()

def test_after():
    pass
"""
QUIET = """
def test_one():
    pass

def test_two():
    pass
"""
LEAVING = """
import subprocess

def test_leaves_a_process():
    subprocess.Popen(["sleep", "300"], start_new_session=True)
"""
CRASH_BETWEEN = """
import faulthandler
import threading

def test_crashes_later():
    threading.Timer(1.0, faulthandler._sigsegv).start()
"""
SLOW = """
import time

def test_slow():
    time.sleep(5)
"""


def run_pytest(folder: Path, files: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    for name, text in files.items():
        (folder / name).write_text(text)
    (folder / "pytest.ini").write_text("[pytest]\ntimeout = 300\n")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "tests.support.run_guard", "-p", "no:cacheprovider",
         "-rA", *args],
        cwd=folder, env=env, capture_output=True, text=True, timeout=RUN_S,
    )  # fmt: skip


def test_a_test_that_crashes_its_worker_fails_the_run_once(tmp_path: Path) -> None:
    done = run_pytest(
        tmp_path, {"test_a.py": CRASHING, "test_b.py": QUIET}, "-n", "2", "--dist", "loadfile"
    )
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    # Once in the short summary (whose width, and so whether the reason is repeated
    # there, depends on the terminal): the crashed test is not run again.
    assert out.count("FAILED test_a.py::test_crash") == 1, out
    assert "crashed while running 'test_a.py::test_crash'" in out, out
    assert "PASSED test_a.py::test_after" in out  # the rest of its file still ran
    assert "PASSED test_b.py::test_two" in out
    assert "crashed test workers" in out


def test_a_worker_crashing_in_its_last_file_fails_the_run_without_hanging(tmp_path: Path) -> None:
    # One worker: it crashes in its last file (the other test's thread, during the slow
    # test); xdist 3.8 alone then waited forever for its replacement.
    done = run_pytest(
        tmp_path, {"test_a.py": CRASH_BETWEEN, "test_b.py": SLOW}, "-n", "1", "--dist", "loadfile"
    )
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    assert "crashed test workers" in out
    assert "crashed while running 'test_b.py::test_slow'" in out


@pytest.mark.parametrize("workers", [[], ["-n", "1"]], ids=["one-process", "xdist"])
def test_a_process_left_running_fails_the_run_named(tmp_path: Path, workers: list[str]) -> None:
    done = run_pytest(tmp_path, {"test_c.py": LEAVING}, *workers)
    out = done.stdout + done.stderr
    assert done.returncode == 1, out
    assert "processes the tests left running (killed)" in out
    assert "(sleep 300)" in out
