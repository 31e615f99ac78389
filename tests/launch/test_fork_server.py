"""The fork server (fleet.launch.fork_server, and its client fork_client): children as
`python -m` would start them, their exit statuses, bad requests answered and survived,
children ending with it, and a child's crash dumped into its log."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleet.launch.fork_client import UNKNOWN_STATUS, ForkedProcess, ForkServer, ForkServerError
from fleet.launch.fork_server import parse_request
from tests.support.processes import ANY_PORT, start_fleet_up, wait_fleet_up
from tests.support.waiting import wait_until

CHILD = "tests.support.fork_child"
TIMEOUT_S = 60.0


@pytest.fixture
def server(tmp_path: Path) -> Iterator[ForkServer]:
    started = ForkServer.start(sys.executable, [CHILD], tmp_path / "server.log", dict(os.environ))
    try:
        started.wait_ready(TIMEOUT_S)
        yield started
    finally:
        started.close()


def env(**extra: str) -> dict[str, str]:
    return {**os.environ, **extra}


#: A child of the server: `CHILD *argv` in this environment (and `extra`), logging to
#: child.log, and that log's path.
Spawn = Callable[..., tuple[ForkedProcess, Path]]


@pytest.fixture
def spawn(server: ForkServer, tmp_path: Path) -> Spawn:
    def spawned(*argv: str, **extra: str) -> tuple[ForkedProcess, Path]:
        log_path = tmp_path / "child.log"
        return server.spawn(CHILD, list(argv), log_path, env(**extra)), log_path

    return spawned


def lines(path: Path) -> list[str]:
    return path.read_text().splitlines() if path.exists() else []


@pytest.mark.parametrize(
    ("line", "why"),
    [
        (b"{not json", "not a JSON line"),
        (b"[1, 2]", "a JSON object"),
        (b'{"module": "os", "argv": [], "log": "x", "env": {}}', "not one this server imported"),
        (b'{"module": "m", "argv": "a b", "log": "x", "env": {}}', "argv is a list"),
        (b'{"module": "m", "argv": [], "log": "", "env": {}}', "log is a file path"),
        (b'{"module": "m", "argv": [], "log": "x", "env": {"A": 1}}', "env maps strings"),
    ],
)
def test_a_malformed_request_says_what_is_wrong(line: bytes, why: str) -> None:
    with pytest.raises(ValueError, match=why):
        parse_request(line, ["m"])


@pytest.mark.e2e
def test_a_child_is_python_dash_m_with_its_arguments_environment_and_log(spawn: Spawn) -> None:
    child, log_path = spawn("exit", "3", FORK_CHILD_SAY="hello")
    assert child.wait(TIMEOUT_S) == 3
    said = lines(log_path)
    assert said[0] == f"argv ['exit', '3'] session {child.pid} pid {child.pid}"  # its own session
    assert said[1] == "say hello"
    assert child.poll() == 3


@pytest.mark.e2e
def test_a_signalled_child_reports_the_signal_as_popen_does(spawn: Spawn) -> None:
    child, log_path = spawn("wait")
    wait_until(lambda: "waiting" in lines(log_path), TIMEOUT_S, "the child to start")
    assert child.poll() is None
    with pytest.raises(subprocess.TimeoutExpired):
        child.wait(0.05)
    child.send_signal(signal.SIGTERM)
    assert child.wait(TIMEOUT_S) == -signal.SIGTERM
    child.kill()  # after its end: signals nothing (its PID may be someone else's now)


@pytest.mark.e2e
def test_an_uncaught_error_is_in_the_childs_log_with_status_1(spawn: Spawn) -> None:
    child, log_path = spawn("raise")
    assert child.wait(TIMEOUT_S) == 1
    assert "RuntimeError: the child's own error" in log_path.read_text()


@pytest.mark.e2e
def test_a_child_that_crashes_leaves_its_python_traceback_in_its_log(spawn: Spawn) -> None:
    child, log_path = spawn("segv")
    assert child.wait(TIMEOUT_S) == -signal.SIGSEGV
    text = log_path.read_text()
    assert "Fatal Python error: Segmentation fault" in text
    assert "fork_child.py" in text  # where it crashed, in Python


@pytest.mark.e2e
def test_a_program_that_crashes_leaves_its_python_traceback_on_stderr() -> None:
    # As `python -m` (no $PYTHONFAULTHANDLER): the program's logging set-up turns it on.
    quiet = {k: v for k, v in os.environ.items() if k != "PYTHONFAULTHANDLER"}
    done = subprocess.run(
        [sys.executable, "-m", CHILD, "segv"], env=quiet, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == -signal.SIGSEGV
    assert "Fatal Python error: Segmentation fault" in done.stderr
    assert "fork_child.py" in done.stderr


@pytest.mark.e2e
def test_a_refused_request_leaves_the_server_serving(server: ForkServer, tmp_path: Path) -> None:
    with pytest.raises(ForkServerError, match="not one this server imported"):
        server.spawn("json.tool", [], tmp_path / "x.log", env())
    assert server.process.stdin is not None  # a line that is no request at all
    server.process.stdin.write(b"\x00\xff garbage\n")
    server.process.stdin.flush()
    child = server.spawn(CHILD, ["exit", "0"], tmp_path / "child.log", env())
    assert child.wait(TIMEOUT_S) == 0


@pytest.mark.e2e
def test_children_end_with_their_server_and_report_an_unknown_status(tmp_path: Path) -> None:
    server = ForkServer.start(sys.executable, [CHILD], tmp_path / "server.log", dict(os.environ))
    log_path = tmp_path / "child.log"
    try:
        server.wait_ready(TIMEOUT_S)
        child = server.spawn(CHILD, ["wait"], log_path, env())
        wait_until(lambda: "waiting" in lines(log_path), TIMEOUT_S, "the child to start")
        server.process.send_signal(signal.SIGKILL)
        server.process.wait(TIMEOUT_S)
        # The kernel kills it with its server (fleet.lifeline); no one can collect its
        # status now: it is known to have ended, not how.
        assert child.wait(TIMEOUT_S) == UNKNOWN_STATUS
    finally:
        server.close()
    with pytest.raises(ForkServerError, match="not running"):
        server.spawn(CHILD, ["exit", "0"], log_path, env())


@pytest.mark.e2e
def test_a_server_that_cannot_import_its_program_says_so_at_once(tmp_path: Path) -> None:
    log_path = tmp_path / "server.log"
    server = ForkServer.start(sys.executable, ["no_such_program"], log_path, dict(os.environ))
    try:
        with pytest.raises(ForkServerError, match="exited with status 1"):
            server.wait_ready(TIMEOUT_S)
    finally:
        server.close()
    assert "No module named 'no_such_program'" in log_path.read_text()


def parent_of(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def pids_by_name(log_dir: Path) -> dict[str, int]:
    rows = (line.split() for line in (log_dir / "pids").read_text().splitlines())
    return {name: int(pid) for pid, name in rows}


@pytest.mark.e2e
@pytest.mark.parametrize("forked", [True, False], ids=["fork-server", "no-fork-server"])
def test_fleet_up_forks_its_onboards_unless_told_not_to(tmp_path: Path, forked: bool) -> None:
    flags = [] if forked else ["--no-fork-server"]
    up = start_fleet_up(
        "--uavs",
        "2",
        "--no-record",
        "--listen",
        ANY_PORT,
        "--log-dir",
        str(tmp_path),
        *flags,
    )
    try:
        wait_fleet_up(up, 90.0)
        pids = pids_by_name(tmp_path)
        onboards = [pids["onboard-101"], pids["onboard-102"]]
        if forked:
            assert all(parent_of(pid) == pids["fork-server"] for pid in onboards)
        else:
            assert "fork-server" not in pids
            assert all(parent_of(pid) == up.process.pid for pid in onboards)
        for pid in onboards:  # either way, each is an onboard module with its own log
            assert b"onboard.main" in Path(f"/proc/{pid}/cmdline").read_bytes()
            assert os.getsid(pid) == pid
        logs = [(tmp_path / f"onboard-{uav}.log").read_text() for uav in (101, 102)]
        assert all("onboard module" in text for text in logs)
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30) == 0, "\n".join(up.history[-20:])
    assert not any(Path(f"/proc/{pid}").exists() for pid in pids_by_name(tmp_path).values())


@pytest.mark.e2e
def test_a_log_that_cannot_be_written_is_the_requests_error(
    server: ForkServer, tmp_path: Path
) -> None:
    with pytest.raises(ForkServerError, match="cannot start"):
        server.spawn(CHILD, ["exit", "0"], tmp_path / "no-such-folder" / "child.log", env())
    child = server.spawn(CHILD, ["exit", "0"], tmp_path / "child.log", env())
    assert child.wait(TIMEOUT_S) == 0
