"""`fleet record` on a real router: what it records, what it drops, how it recovers
(`fleet record` run by its root in the test's process)."""

from __future__ import annotations

import contextlib
import itertools
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import StatusText
from fleet.piccolo.telemetry import GpsBlock, Telemetry
from fleet.recording.bus_tap import state_period
from fleet.recording.reader import read_recording
from fleet.recording.recorder import Recorder
from fleet.recording.replay import replayable
from fleet.recording.writer import McapSink
from fleet.transport.bus_codec import ENCODING, encode
from fleet.transport.zenoh_bus import ZenohBus
from tests.support.ground_cli import fleet_here
from tests.support.processes import client_session, refused_endpoint, router_session
from tests.support.waiting import wait_until

SPACE = KeySpace()


def _matching(publisher: zenoh.Publisher) -> bool:
    status: object = publisher.matching_status  # a MatchingStatus; zenoh's stub says bool
    return bool(getattr(status, "matching", False))


def wait_recorded(recorder: Recorder, pattern: str, count: int, what: str) -> None:
    wait_until(lambda: recorder.stats.recorded[pattern] == count, 10.0, what)


@contextlib.contextmanager
def recording_to(path: Path, first_key: str) -> Iterator[tuple[zenoh.Session, Recorder]]:
    """A recorder on a ground session of a router of this process, writing `path`, and a
    fleet session that can put once the router knows the recorder's subscription to
    `first_key` (puts before that reach nobody on a busy machine)."""
    with (
        router_session() as router,
        client_session(router.endpoints[0]) as fleet,
        client_session(router.endpoints[0]) as ground,
    ):
        recorder = Recorder(ZenohBus(ground), McapSink(path), state_every_s=0)
        recorder.start()
        try:
            publisher = fleet.declare_publisher(first_key)
            wait_until(lambda: _matching(publisher), 10.0, "the subscription")
            publisher.undeclare()
            yield fleet, recorder
        finally:
            recorder.stop()


def test_records_puts_and_tokens_and_drops_what_is_not_json(tmp_path: Path) -> None:
    with recording_to(tmp_path / "r.mcap", SPACE.status(7)) as (fleet, recorder):
        token = fleet.liveliness().declare_token(SPACE.alive(7))
        fleet.put(SPACE.status(7), encode(StatusText("hello")), encoding=ENCODING)
        fleet.put(SPACE.status(7), b"\xff\x00 not json")
        nested = b'{"a":' * 50_000 + b"1" + b"}" * 50_000
        # Blocking: a large put may otherwise be dropped when the queue is full.
        fleet.put(SPACE.status(7), nested, congestion_control=zenoh.CongestionControl.BLOCK)
        wait_until(
            lambda: (
                recorder.stats.dropped["not JSON"] == 1
                and recorder.stats.dropped["too_deep"] == 1
                and recorder.stats.recorded["fleet/uav/*/status"] == 1
            ),
            10.0,
            "the recorder to hear both puts",
        )
        token.undeclare()
        wait_recorded(recorder, "fleet/uav/*/alive", 2, "the token to come and go")
    recording = read_recording(tmp_path / "r.mcap")
    values = [(m.topic, m.value()) for m in recording.messages]
    hello = {"text": "hello", "kind": "info", "mission": None, "target": None, "severity": "info"}
    assert ("fleet/uav/7/status", hello) in values
    alive = [value for topic, value in values if topic == "fleet/uav/7/alive"]
    assert alive == [{"alive": True}, {"alive": False}] and len(values) == 3
    assert recording.channels["fleet/uav/7/alive"].schema_name == "fleet.Liveliness"


def test_in_the_router_samples_wait_in_zenoh_and_map_fixes_come_once_a_second(
    tmp_path: Path,
) -> None:
    """`fleet up`'s recorder: on the router's own session, Zenoh queues the samples (no
    Python on the routing threads); telemetry at 20 Hz gives one map fix a second (every
    telemetry recorded here: `telemetry_every_s=0`)."""
    with router_session() as router, client_session(router.endpoints[0]) as fleet:
        recorder = Recorder(
            ZenohBus(router.session),
            McapSink(tmp_path / "r.mcap"),
            state_every_s=0,
            in_router=True,
            telemetry_every_s=0,
        )
        recorder.start()
        try:
            telemetry = Telemetry(0, gps=GpsBlock(35.7, -120.7, 600.0, 0.0, 22.0, 0.0))
            wait_until(
                lambda: (
                    fleet.put(SPACE.telemetry(7), encode(telemetry))
                    or recorder.stats.recorded["fleet/uav/*/telemetry"] > 0
                ),
                10.0,
                "the recorder to hear the client",
            )
            for _ in range(30):  # 1.5 s at 20 Hz
                fleet.put(SPACE.telemetry(7), encode(telemetry))
                time.sleep(0.05)
            fleet.put(SPACE.status(7), encode(StatusText("last")))
            wait_recorded(recorder, "fleet/uav/*/status", 1, "the last put")
        finally:
            recorder.stop()
    recording = read_recording(tmp_path / "r.mcap")
    times = [m.log_time_ns for m in recording.messages if m.topic.endswith("/telemetry")]
    fixes = [m.log_time_ns for m in recording.messages if m.topic.endswith("/location_fix")]
    assert len(times) >= 31 and fixes[0] == times[0]
    # One a second (from the first telemetry at or past a second after the last fix).
    for previous, fix in itertools.pairwise(fixes):
        assert fix == min(t for t in times if t >= previous + 10**9)
    assert times[-1] < fixes[-1] + 10**9 and len(fixes) >= 2


def test_a_large_fleet_is_asked_its_states_at_most_ten_a_second() -> None:
    assert state_period(1.0, 2) == 1.0 and state_period(1.0, 10) == 1.0
    assert state_period(1.0, 50) == 5.0 and state_period(1.0, 100) == 10.0
    assert state_period(30.0, 100) == 30.0  # --state-every is the shortest period


def _fleet(*argv: str) -> subprocess.CompletedProcess[str]:
    return fleet_here(*argv)


def test_record_without_a_router_says_so(tmp_path: Path) -> None:
    with refused_endpoint() as nowhere:
        done = _fleet("record", str(tmp_path / "x.mcap"), "--connect", nowhere)
    assert done.returncode == 2
    assert "no Zenoh router answers" in done.stderr
    assert not (tmp_path / "x.mcap").exists()


def test_record_for_a_duration_then_recover_a_killed_copy(tmp_path: Path) -> None:
    out = tmp_path / "d.mcap"
    with router_session() as router:
        done = _fleet("record", str(out), "--duration", "0.5", "--connect", router.endpoints[0])
    assert done.returncode == 0, done.stderr
    assert "fleet record: 0 messages" in done.stdout
    assert read_recording(out).messages == []  # nothing heard: a valid, empty recording
    # A recording cut short is repaired in place:
    from tests.recording.test_writer_reader import _write

    sink = McapSink(tmp_path / "live.mcap")
    _write(sink, 5)
    sink.flush()
    shutil.copy(tmp_path / "live.mcap", out)
    sink.close()
    fixed = _fleet("record", "--recover", str(out))
    assert fixed.returncode == 0, fixed.stderr
    assert "5 messages kept; it had ended early" in fixed.stdout
    assert read_recording(out).truncated == {}
    (tmp_path / "junk.mcap").write_bytes(b"junk")
    refused = _fleet("record", "--recover", str(tmp_path / "junk.mcap"))
    assert refused.returncode == 1 and "not an MCAP recording" in refused.stderr


def test_record_refuses_a_path_it_cannot_write_and_a_bad_expression(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("")
    with router_session() as router:
        connect = ("--connect", router.endpoints[0])
        unwritable = _fleet("record", str(tmp_path / "file" / "x.mcap"), *connect)
        bad_expr = _fleet("record", str(tmp_path / "y.mcap"), "fleet//x", *connect)
    assert unwritable.returncode == 1
    assert "fleet record: cannot write" in unwritable.stderr and "x.mcap" in unwritable.stderr
    assert bad_expr.returncode == 2, bad_expr.stderr
    # One line, what is wrong and how to write one; refused before any file is made.
    assert bad_expr.stderr.splitlines() == [
        "fleet record: error: 'fleet//x' is not a key expression (empty chunks are "
        "forbidden, as well as leading and trailing slashes): write chunks separated by "
        "single `/`, with `*` for any one chunk and `**` for any number of them "
        "(e.g. fleet/** or fleet/uav/*/telemetry)"
    ]
    assert not (tmp_path / "y.mcap").exists()


def test_a_full_disk_stops_the_recorder_with_the_reason(tmp_path: Path) -> None:
    with router_session() as router:
        done = _fleet("record", "/dev/full", "--connect", router.endpoints[0])
    assert done.returncode == 1
    assert "cannot write /dev/full: No space left on device" in done.stderr


def test_commands_and_map_fixes_are_never_replayed() -> None:
    from fleet.recording.reader import RecordedMessage

    def message(topic: str, schema: str = "") -> RecordedMessage:
        return RecordedMessage(topic, "", schema, 0, 0, b"{}")

    assert replayable(message("fleet/uav/1/telemetry", "Telemetry"))
    assert replayable(message("fleet/mission/3/assignment/1", "AssignmentReport"))
    assert not replayable(message("fleet/mission/3/targets", "MissionTargets"))
    assert not replayable(message("fleet/mission/3/abort", "MissionAbort"))
    assert not replayable(message("fleet/uav/1/opm", "OpmCommand"))
    assert not replayable(message("fleet/uav/1/location_fix", "foxglove.LocationFix"))


def test_ever_new_unknown_keys_do_not_grow_the_recording_without_bound(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("fleet.recording.recorder.MAX_UNKNOWN_KEYS", 3)
    with recording_to(tmp_path / "r.mcap", "fleet/uav/7/junk-0") as (fleet, recorder):
        for i in range(5):  # a UAV may write anything under its own tree
            fleet.put(f"fleet/uav/7/junk-{i}", b"1", encoding=ENCODING)
        wait_until(
            lambda: recorder.stats.dropped["too many unknown keys"] == 2,
            10.0,
            "the keys beyond the limit counted",
        )
    topics = {m.topic for m in read_recording(tmp_path / "r.mcap").messages}
    assert len(topics) == 3 and all(t.startswith("fleet/uav/7/junk-") for t in topics)
