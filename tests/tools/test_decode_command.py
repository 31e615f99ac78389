"""`fleet decode`: run by `fleet`'s root in the test's process, and once as the installed
command runs it (`python -m programs.fleet_cli`)."""

import io
import json
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest

from fleet.mission.messages import MISSION_MANAGER, StatusText
from fleet.payload.link import PiccoloLink
from fleet.payload.protocol import encode_message
from fleet.transport.cli import ExitCode
from programs.fleet_cli import main
from tests.support.link_samples import sample_telemetry

FIXTURES = Path(__file__).parent.parent / "fixtures"


def _fleet_decode_process(capture: str, data: bytes = b"") -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(
        [sys.executable, "-m", "programs.fleet_cli", "decode", capture],
        input=data,
        capture_output=True,
        timeout=60,
    )


def _fleet_decode(
    capture: str, data: bytes = b"", monkeypatch: pytest.MonkeyPatch | None = None
) -> subprocess.CompletedProcess[bytes]:
    """`fleet decode CAPTURE` in this process, `data` on its standard input."""
    if monkeypatch is not None:
        monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        status = main(["decode", capture])
    return subprocess.CompletedProcess(
        ["fleet", "decode", capture], status, out.getvalue().encode(), err.getvalue().encode()
    )


def _records(done: subprocess.CompletedProcess[bytes]) -> list[dict[str, object]]:
    assert done.returncode == ExitCode.OK, done.stderr
    return [json.loads(line) for line in done.stdout.splitlines()]


@pytest.mark.e2e
def test_fleet_decode_prints_each_packet_then_the_drop_counters() -> None:
    capture = (FIXTURES / "capture_track_report.bin").read_bytes()
    records = _records(_fleet_decode_process("-", b"\x00garbage" + capture))
    assert records[0] == {
        "header": {
            "source": 112,
            "destination": 0xFFFE,
            "stream": 3,
            "sequence": 8,
            "acknowledge": 0,
        },
        "layer": "autopilot",
        "kind": "track",
        "message": {"waypoint": 3, "go_to": 0},
    }
    assert records[-1]["drops"]["stream_skipped_bytes"] == 8  # type: ignore[index]


def test_fleet_decode_names_kinds_in_si_units(monkeypatch: pytest.MonkeyPatch) -> None:
    sender = PiccoloLink(112)
    wire = sender.encode_autopilot(sample_telemetry(), 0xFFFE) + sender.encode_payload(
        encode_message(StatusText("hello"), 112, MISSION_MANAGER), 0xFFFE
    )
    telemetry, status, drops = _records(_fleet_decode("-", wire, monkeypatch))
    assert telemetry["kind"] == "telemetry"
    gps = telemetry["message"]["gps"]  # type: ignore[index]
    assert abs(gps["lat"] - 42.36) < 1e-6 and gps["vel_east"] == 21.5
    assert status["kind"] == "status" and status["message"] == {
        "text": "hello",
        "kind": "info",  # the payload edge's generic kind
        "mission": None,
        "target": None,
        "severity": "info",
    }
    assert drops["packets"] == 2


def test_fleet_decode_survives_pure_garbage(tmp_path: Path) -> None:
    path = tmp_path / "noise.bin"
    path.write_bytes(bytes(range(256)) * 50)
    (last,) = _records(_fleet_decode(str(path)))
    assert last["drops"]["stream_skipped_bytes"] > 0  # type: ignore[index]


def test_fleet_decode_names_a_capture_it_cannot_read(tmp_path: Path) -> None:
    missing = tmp_path / "missing.bin"
    done = _fleet_decode(str(missing))
    assert done.returncode == ExitCode.USAGE
    assert done.stdout == b""
    assert done.stderr.decode() == (
        f"fleet decode: cannot read {missing}: No such file or directory\n"
    )
