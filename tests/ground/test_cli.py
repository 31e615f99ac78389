"""`ground-cli` from its root to the bus: the real program (`ground.cli.main`, its
parser, its commands) run in the test's process on the in-process bus, with two
`FakeOnboard`s (tests/support/fake_onboard.py), test doubles of the onboard process.
What needs a real router (its admin space) is in test_cli_keys.py.
"""

from __future__ import annotations

import io
import itertools
import json
import struct
import subprocess
import threading
from pathlib import Path

import pytest

from fleet.consensus.assignment import greedy_assign
from fleet.files.targets_io import write_targets
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import (
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    RouterState,
    StatusText,
    Target,
    UavResult,
)
from fleet.mission.phase import Phase
from fleet.mission.status_kind import StatusKind
from fleet.transport.bus import Bus
from fleet.transport.bus_factory import opened_bus
from fleet.transport.zenoh_config import CONFIG_ENV, CONNECT_ENV
from ground.fleet_commands import WatchOptions, run_watch
from ground.mission_outcome import MissionOutcome, check_agreement
from tests.support.fake_onboard import FakeOnboard, approach_time
from tests.support.ground_cli import ground_cli_here
from tests.support.processes import refused_endpoint
from tests.support.waiting import wait_until

SPACE = KeySpace()

REPO = Path(__file__).resolve().parents[2]
CLI_TIMEOUT_S = 30.0
TARGETS = (
    Target(42.3601, -71.0900, 120.0),
    Target(42.3650, -71.1000, 110.0),
    Target(42.3550, -71.0950, 130.0),
)

#: Mission ids of markers no command uses, a new one each time.
MARKER_MISSIONS = itertools.count(0xFFFF_0000)


def run_cli(*args: str, endpoint: str | None) -> subprocess.CompletedProcess[str]:
    """`ground-cli ARGS` with `--connect endpoint` (None: none), in this process."""
    return ground_cli_here(*args, connect=endpoint)


@pytest.fixture(scope="module")
def router(memory_router: str) -> str:
    """The fleet's bus: an in-process one (`memory:NAME`), as `--connect` takes it."""
    return memory_router


# ---- against a router with two fake UAVs --------------------------------------------------------
def test_uavs_json_lists_the_live_uavs(router: str, fakes: dict[int, FakeOnboard]) -> None:
    done = run_cli("uavs", "--json", endpoint=router)
    assert done.returncode == 0, done.stderr
    rows = {row["id"]: row for row in json.loads(done.stdout)}
    assert sorted(rows) == [74, 112]
    for uav, fake in fakes.items():
        assert rows[uav]["lat"] == pytest.approx(fake.lat)
        assert rows[uav]["lon"] == pytest.approx(fake.lon)
        assert rows[uav]["alt"] == pytest.approx(fake.alt)
        assert rows[uav]["heading"] == pytest.approx(90.0)
        assert rows[uav]["ground_speed"] == pytest.approx(20.0)
        assert rows[uav]["tracked_waypoint"] == 3
        assert rows[uav]["enabled"] is True


def test_uavs_table(router: str, fakes: dict[int, FakeOnboard]) -> None:
    done = run_cli("uavs", endpoint=router)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].split()[:3] == ["ID", "LAT", "LON"]
    assert [line.split()[0] for line in lines[1:]] == ["74", "112"]


def test_send_targets_wait_json(router: str, fakes: dict[int, FakeOnboard], tmp_path: Path) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    # 112 only serves its report by query: the ground's fetch must still find it.
    fakes[112].publish_assignment = False
    try:
        done = run_cli(
            "send-targets", str(path), "--wait", "--json", "--timeout", "15", endpoint=router
        )
    finally:
        fakes[112].publish_assignment = True
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    mission = out["mission"]
    assert isinstance(mission, int) and mission >= 1
    assert out["team"] == [74, 112]
    assert out["results"] == {
        str(u): [approach_time(u, i) for i in range(len(TARGETS))] for u in (74, 112)
    }
    expected = greedy_assign(
        {u: [approach_time(u, i) for i in range(len(TARGETS))] for u in (74, 112)}, len(TARGETS)
    )
    assert out["assignment"] == {str(u): t for u, t in expected.pairs.items()}
    assert out["unassigned"] == list(expected.unassigned_targets)
    assert out["agreed"] is True
    assert out["disagreed"] == []
    assert out["complete"] is True
    assert out["timed_out"] is False
    # Progress went to stderr, so stdout is exactly one JSON object.
    assert "committed target" in done.stderr
    for fake in fakes.values():
        got = [t for t in fake.targets if t.mission == mission]
        assert got and got[0].team == (74, 112)
        assert got[0].targets == TARGETS

    # The next mission gets a higher id: the fakes still answer for this one.
    again = run_cli("send-targets", str(path), "--team", "74", "--json", endpoint=router)
    assert again.returncode == 0, again.stderr
    second = json.loads(again.stdout)
    assert second["mission"] == mission + 1
    assert second["team"] == [74]
    assert wait_until(lambda: any(t.mission == mission + 1 for t in fakes[74].targets))


def test_send_targets_names_who_disagreed(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    fakes[112].disagree = True
    try:
        done = run_cli("send-targets", str(path), "--wait", "--json", endpoint=router)
    finally:
        fakes[112].disagree = False
    assert done.returncode == 1, done.stderr
    out = json.loads(done.stdout)
    assert out["agreed"] is False
    # A tie of two single-member groups: the lower Piccolo ID is the reference.
    assert out["disagreed"] == [112]
    assert out["complete"] is True


@pytest.mark.parametrize(
    ("data", "where"),
    [
        (b"\x00" * 30, "target 1 at byte offset 24"),
        (b"\x00" * 24 + b"\xff" * 24, "target 1 at byte offset 24: latitude is nan"),
        (
            b"lat,lon,alt\n35.72,-120.76,600\n35.68,-120.74,600\n35.7500,-120.8000,600.0\n",
            "this is a text file",
        ),
        (struct.pack("<6d", 35.7, -120.7, 600.0, 35.7, -120.7, -1e9), "altitude -1000000000.0"),
    ],
)
def test_bad_targets_file_is_refused_and_nothing_sent(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path, data: bytes, where: str
) -> None:
    path = tmp_path / "bad.bin"
    path.write_bytes(data)
    before = {uav: len(fake.targets) for uav, fake in fakes.items()}
    done = run_cli("send-targets", str(path), "--wait", "--timeout", "2", endpoint=router)
    assert done.returncode == 1
    assert str(path) in done.stderr
    assert where in done.stderr
    assert "nothing sent" in done.stderr
    assert_nothing_sent_since(router, fakes, before)


def assert_nothing_sent_since(
    router: str, fakes: dict[int, FakeOnboard], before: dict[int, int]
) -> None:
    """No fake heard a mission since it had heard `before[uav]` of them."""
    # A marker sent now through the same router arrives after anything the command put
    # before it exited (its session's close flushes): once every fake has the marker,
    # a put from the command would have been seen.
    marker = MissionTargets(mission=next(MARKER_MISSIONS), team=(1,), targets=())
    with opened_bus(router) as bus:
        bus.publish(SPACE.mission_targets(marker.mission), marker)
        assert wait_until(lambda: all(marker in fake.targets for fake in fakes.values()))
    assert {uav: len(fake.targets) for uav, fake in fakes.items()} == {
        uav: count + 1 for uav, count in before.items()
    }


def test_opm_arrives_with_its_payload(router: str, fakes: dict[int, FakeOnboard]) -> None:
    done = run_cli("opm", "74", "off", "--status-rate", "2.5", endpoint=router)
    assert done.returncode == 0, done.stderr
    assert wait_until(lambda: OpmCommand(enabled=False, status_rate_hz=2.5) in fakes[74].opms)
    assert "module off" in done.stdout  # the UAV's confirming status message
    assert not fakes[112].opms

    done = run_cli("opm", "74", "on", endpoint=router)
    assert done.returncode == 0, done.stderr
    assert wait_until(lambda: fakes[74].opms[-1:] == [OpmCommand(True, 1.0)])

    absent = run_cli("opm", "999", "on", endpoint=router)
    assert absent.returncode == 1
    assert "999 is not live" in absent.stderr


def send_mission(router: str, fakes: dict[int, FakeOnboard], tmp_path: Path) -> int:
    """Send TARGETS with `send-targets`; its mission id, once every fake holds it."""
    path = tmp_path / "targets.bin"
    write_targets(path, TARGETS)
    sent = run_cli("send-targets", str(path), "--json", endpoint=router)
    assert sent.returncode == 0, sent.stderr
    mission: int = json.loads(sent.stdout)["mission"]
    assert wait_until(
        lambda: all(f.mission and f.mission.mission == mission for f in fakes.values())
    )
    return mission


def test_uavs_json_gives_each_uav_its_mission_target_phase_and_link_age(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    mission = send_mission(router, fakes, tmp_path)
    done = run_cli("uavs", "--json", endpoint=router)
    assert done.returncode == 0, done.stderr
    rows = {row["id"]: row for row in json.loads(done.stdout)}
    for uav, fake in fakes.items():
        assert fake.mission is not None and fake.mission.assignment is not None
        row = rows[uav]
        assert row["mission"] == mission
        assert row["target"] == fake.mission.assignment.target
        assert row["phase"] == str(fake.state().phase)
        assert row["reason"] is None
        # The fakes report no link health: the key is there, its value unknown.
        assert "link_age_s" in row and row["link_age_s"] is None


def test_abort_arrives_for_the_current_or_named_mission(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    mission = send_mission(router, fakes, tmp_path)

    done = run_cli("abort", endpoint=router)
    assert done.returncode == 0, done.stderr
    assert f"mission {mission}" in done.stdout
    for fake in fakes.values():
        assert wait_until(lambda fake=fake: MissionAbort(mission) in fake.aborts)

    assert "aborted by 74, 112" in done.stdout  # every UAV confirmed with its phase

    # A mission the fleet never saw is an error, and nothing is sent.
    done = run_cli("abort", "--mission", "4242", endpoint=router)
    assert done.returncode == 1
    assert "mission 4242 is unknown to the fleet" in done.stderr
    marker = run_cli("abort", "--mission", str(mission), endpoint=router)
    assert marker.returncode == 0, marker.stderr
    assert wait_until(lambda: fakes[112].aborts.count(MissionAbort(mission)) == 2)
    assert MissionAbort(4242) not in fakes[112].aborts


def test_mission_until_reached_says_which_targets_were_not_reached_and_why(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    fakes[74].serves_targets = True
    try:
        mission = send_mission(router, fakes, tmp_path)
    finally:
        fakes[74].serves_targets = False
    done = run_cli("mission", "--until-reached", "0.5", endpoint=router)
    assert done.returncode == 1
    # The fakes never reach anything: each target is named with who holds it, or why not.
    assert f"mission {mission}: not every target reached within 0.5 s" in done.stderr
    holders: dict[int, int] = {}
    for uav, fake in fakes.items():
        assert fake.mission is not None and fake.mission.assignment is not None
        if (target := fake.mission.assignment.target) is not None:
            holders[target] = uav
    for target in range(len(TARGETS)):
        line = next(x for x in done.stderr.splitlines() if x.startswith(f"  target {target}: "))
        if target in holders:
            assert f"not reached: UAV {holders[target]} holds it" in line, line
        else:
            assert "unserved: " in line, line
    # Without --until-reached, no such list: the summary says it all.
    assert "not every target reached" not in run_cli("mission", endpoint=router).stderr


def test_abort_of_one_uav_leaves_its_teammate_on_the_mission(
    router: str, fakes: dict[int, FakeOnboard], tmp_path: Path
) -> None:
    mission = send_mission(router, fakes, tmp_path)
    done = run_cli("abort", "--mission", str(mission), "--uav", "74", endpoint=router)
    assert done.returncode == 0, done.stderr
    assert f"mission {mission}: aborted by 74\n" in done.stdout
    assert fakes[74].mission is not None and fakes[74].mission.phase == Phase.ABORTED
    assert fakes[112].mission is not None and fakes[112].mission.phase == Phase.COMMITTED
    assert MissionAbort(mission, uav=74) in fakes[112].aborts  # seen, and not obeyed


def test_watch_shows_the_table_and_status_messages(
    router: str, fakes: dict[int, FakeOnboard]
) -> None:
    done = run_cli("watch", "--count", "3", "--interval", "0.4", endpoint=router)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert sum(line.startswith("-- ") for line in lines) == 3
    rows = [line.split()[0] for line in lines if line.split() and line.split()[0].isdigit()]
    assert "74" in rows and "112" in rows
    assert any("UAV 74: fake 74 tick" in line for line in lines), done.stdout


def test_watch_keeps_a_warning_in_view_while_info_streams_past(
    router: str, fakes: dict[int, FakeOnboard]
) -> None:
    frames = _Frames()
    done: list[int] = []
    with opened_bus(router) as bus:
        options = WatchOptions(count=6, interval=0.3)
        watch = threading.Thread(target=lambda: done.append(run_watch(bus, options, frames)))
        watch.start()
        try:
            # The first frame: watch is subscribed.
            assert frames.first.wait(CLI_TIMEOUT_S), frames.getvalue()
            # The severity the message carries counts, not its wording.
            fakes[112].put(SPACE.status(112), StatusText("GPS fix degraded", StatusKind.WARNING))
        finally:
            watch.join(CLI_TIMEOUT_S)
    out = frames.getvalue()
    assert done == [0], out
    lines = out.splitlines()
    # Appended as it arrived, severity first...
    assert any(
        line.startswith("warning ") and line.endswith("UAV 112: GPS fix degraded") for line in lines
    ), out
    assert any(line.startswith("info ") and "UAV 74: fake 74 tick" in line for line in lines)
    # ...and pinned under every frame after it, however many info lines came since.
    last_frame = out.rsplit("\n-- ", 1)[1]
    assert "warnings and errors (pinned):" in last_frame, out
    assert "UAV 112: GPS fix degraded" in last_frame


class _Frames(io.StringIO):
    """What `watch` writes; `first` is set once a frame began."""

    def __init__(self) -> None:
        super().__init__()
        self.first = threading.Event()

    def write(self, text: str) -> int:
        written = super().write(text)
        if text.startswith("-- "):
            self.first.set()
        return written


# ---- without a router ---------------------------------------------------------------------
def test_no_router_is_a_clear_error_not_a_hang() -> None:
    with refused_endpoint() as endpoint:
        for command in (["uavs"], ["keys"], ["abort", "--mission", "1"]):
            done = run_cli(*command, endpoint=endpoint)
            assert done.returncode == 2
            assert f"no Zenoh router answers at {endpoint}" in done.stderr
            assert "Traceback" not in done.stderr


def test_connect_comes_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    with refused_endpoint() as endpoint:
        monkeypatch.delenv(CONFIG_ENV, raising=False)
        monkeypatch.setenv(CONNECT_ENV, endpoint)
        done = run_cli("uavs", endpoint=None)
    assert done.returncode == 2
    assert endpoint in done.stderr


# ---- targets files (no network) -----------------------------------------------------------
def test_targets_make_and_show(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ground.cli import main

    path = tmp_path / "t.bin"
    assert (
        main(["targets", "make", "--out", str(path), "42.36,-71.09,120", "--", "-33.9,151.2,80"])
        == 0
    )
    assert path.stat().st_size == 48
    capsys.readouterr()
    assert main(["targets", "show", str(path), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown == [
        {"index": 0, "lat": 42.36, "lon": -71.09, "alt": 120.0},
        {"index": 1, "lat": -33.9, "lon": 151.2, "alt": 80.0},
    ]
    assert main(["targets", "make", "--out", str(path), "91,0,10"]) == 1
    err = capsys.readouterr().err
    assert "target 0" in err and "latitude" in err
    assert path.stat().st_size == 48  # the good file is untouched
    assert main(["targets", "make", "--out", str(path), "1,2"]) == 1
    assert "LAT,LON,ALT" in capsys.readouterr().err


# ---- agreement (pure) ------------------------------------------------------------------------
def _report(uav: int, digest: str, pairs: dict[int, int]) -> AssignmentReport:
    return AssignmentReport(
        mission=1,
        uav=uav,
        target=pairs.get(uav),
        pairs=pairs,
        unassigned=(),
        team=(1, 2, 3),
        digest=digest,
    )


def test_agreement_names_the_minority_and_the_missing() -> None:
    pairs = {1: 0, 2: 1, 3: 2}
    reports = {1: _report(1, "a", pairs), 2: _report(2, "a", pairs), 3: _report(3, "b", pairs)}
    agreement = check_agreement((1, 2, 3), reports)
    assert not agreement.agreed
    assert agreement.disagreed == (3,)
    assert agreement.reference is reports[1]
    partial = check_agreement((1, 2, 3, 4), {1: reports[1], 2: reports[2]})
    assert not partial.agreed and partial.missing == (3, 4) and partial.disagreed == ()
    assert check_agreement((1, 2, 3), reports | {3: _report(3, "a", pairs)}).agreed


def test_outcome_json_fills_nulls_for_silent_uavs() -> None:
    outcome = MissionOutcome(mission=9, team=(1, 2), targets=TARGETS[:2])
    outcome.results[1] = UavResult(9, 1, (5.0, None))
    out = outcome.to_json()
    assert out["results"] == {"1": [5.0, None], "2": [None, None]}
    assert out["assignment"] == {"1": None, "2": None}
    assert out["unassigned"] == [0, 1]
    assert out["agreed"] is False
    assert out["missing_results"] == [2]


# ---- routers (each secure router's refused links) -------------------------------------------
class _Router:
    """A router's state query, answered on the bus (as fleet/transport/router.py does)."""

    def __init__(self, bus: Bus, state: RouterState) -> None:
        self.state = state
        self.queryable = bus.declare_queryable(SPACE.router_state(), self._answer)

    def _answer(self) -> None:
        while (query := self.queryable.try_recv()) is not None:
            query.reply(SPACE.router_state(), self.state)
            query.drop()


def test_routers_lists_each_router_that_answers_once_by_zid(router: str) -> None:
    with opened_bus(router) as bus:
        assert run_cli("routers", endpoint=router).stdout == "no secure router answered\n"
        # Both answer on one key (a mesh has several routers): each reply is kept.
        answering = [
            _Router(bus, RouterState("b2", {"no_certificate": 2})),
            _Router(bus, RouterState("a1", {})),
        ]
        listed = run_cli("routers", endpoint=router)
        assert listed.returncode == 0, listed.stderr
        assert listed.stdout.splitlines() == [
            "router a1: refused links: none",
            "router b2: refused links: no_certificate=2",
        ]
        as_json = json.loads(run_cli("routers", "--json", endpoint=router).stdout)
        for answer in answering:
            answer.queryable.undeclare()
    assert as_json == [
        {"identity": None, "zid": "a1", "refused_links": {}},
        {"identity": None, "zid": "b2", "refused_links": {"no_certificate": 2}},
    ]
