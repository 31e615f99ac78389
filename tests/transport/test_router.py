"""The embedded Zenoh router (`fleet.transport.router`) and the fleet launcher built around it.

Real sessions on loopback, free ports. The launcher tests replace the onboard process
with a liveliness-only test double (`FAKE_ONBOARD`): the simulator is real, the planning
module is not (the lead's end-to-end tests run the real one).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from fleet.launch.endpoints import client_endpoint, free_port, host_port, parse_sim_line
from fleet.launch.launcher import Fleet, FleetSpec, LaunchError
from fleet.launch.ring import ring_scenario
from fleet.mission.key_space import KeySpace
from fleet.transport.router import Router, RouterError, parse_listening
from fleet.transport.zenoh_config import make_config
from tests.support.fake_onboard import FAKE_ONBOARD
from tests.support.processes import ANY_PORT, start_router

SPACE = KeySpace()

REPO = Path(__file__).resolve().parents[2]


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def kill_if_alive(pid: int) -> None:
    if alive(pid):
        os.kill(pid, signal.SIGKILL)


@pytest.fixture
def router() -> Iterator[str]:
    """Where a router listens: on a port the OS picked (port 0)."""
    with Router([ANY_PORT]) as running:
        yield running.endpoints[0]


# ---- the router ---------------------------------------------------------------------------
def test_router_relays_between_clients_and_serves_its_admin_space(router: str) -> None:
    received = threading.Event()
    got: list[bytes] = []

    def on_sample(sample: zenoh.Sample) -> None:
        got.append(sample.payload.to_bytes())
        received.set()

    with (
        zenoh.open(make_config("client", [router])) as a,
        zenoh.open(make_config("client", [router])) as b,
        b.declare_subscriber("fleet/test/**", on_sample),
    ):
        for _ in range(50):  # until the subscription has reached the router
            a.put("fleet/test/x", b"hello")
            if received.wait(0.1):
                break
        assert got and got[0] == b"hello"
        admin = [str(r.ok.key_expr) for r in b.get("@/**", timeout=2.0) if r.ok is not None]
        assert any(key.endswith("/router") for key in admin), admin


def test_router_on_a_taken_port_is_a_clear_error(router: str) -> None:
    with pytest.raises(RouterError, match=router), Router([router]):
        pass


def test_a_router_on_port_0_says_the_ports_it_bound_and_is_reached_there() -> None:
    with Router(["tcp/127.0.0.1:0", "tcp/[::1]:0"]) as router:
        v4, v6 = router.endpoints
        assert v4.startswith("tcp/127.0.0.1:") and v6.startswith("tcp/[::1]:")
        assert host_port(v4)[1] != 0 and host_port(v6)[1] != 0
        for endpoint in router.endpoints:
            with zenoh.open(make_config("client", [endpoint])) as client:
                assert str(router.session.zid()) in map(str, client.info.routers_zid())


def test_a_router_on_a_wildcard_port_0_is_reached_on_loopback() -> None:
    with Router(["tcp/0.0.0.0:0"]) as router:
        (endpoint,) = router.endpoints
        assert endpoint.startswith("tcp/0.0.0.0:") and host_port(endpoint)[1] != 0
        with zenoh.open(make_config("client", [client_endpoint(endpoint)])) as client:
            assert str(router.session.zid()) in map(str, client.info.routers_zid())


def test_parse_listening_reads_only_its_own_line() -> None:
    assert parse_listening("router listening on tcp/127.0.0.1:7447\n") == "tcp/127.0.0.1:7447"
    assert parse_listening("2026 INFO zenoh router abc listening on tcp/1.2.3.4:1") is None


def test_router_needs_an_endpoint() -> None:
    with pytest.raises(ValueError, match="a router needs at least one listen endpoint"):
        Router([])


@pytest.mark.e2e
def test_a_router_process_on_port_0_prints_where_it_listens() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "fleet.transport.router", "--listen", "tcp/127.0.0.1:0"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert process.stdout is not None
        endpoint = None
        while endpoint is None:
            line = process.stdout.readline()
            assert line, "the router ended without saying where it listens"
            endpoint = parse_listening(line)
        assert host_port(endpoint)[1] != 0
        with zenoh.open(make_config("client", [endpoint])) as client:
            assert len(list(client.info.routers_zid())) == 1
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=10) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        if process.stdout is not None:
            process.stdout.close()


@pytest.mark.e2e
def test_router_process_stops_on_sigterm() -> None:
    router, endpoint = start_router("--listen", ANY_PORT)
    try:
        with zenoh.open(make_config("client", [endpoint])):
            pass
        router.process.send_signal(signal.SIGTERM)
        assert router.process.wait(timeout=10) == 0
    finally:
        router.kill()


# ---- the launcher ---------------------------------------------------------------------------
def test_parse_sim_line() -> None:
    line = "uav 112 program=socket://127.0.0.1:5760 payload=socket://127.0.0.1:5860 ground=socket://127.0.0.1:5960"
    endpoints = parse_sim_line(line)
    assert endpoints is not None
    assert endpoints.piccolo_id == 112
    assert endpoints.program == "socket://127.0.0.1:5760"
    assert endpoints.payload == "socket://127.0.0.1:5860"
    assert endpoints.ground == "socket://127.0.0.1:5960"
    assert parse_sim_line("ready") is None
    assert parse_sim_line("uav 7 nothing") is None


def test_client_endpoint_of_a_wildcard_listen() -> None:
    assert client_endpoint("tcp/0.0.0.0:7447") == "tcp/127.0.0.1:7447"
    assert client_endpoint("tcp/[::]:7447") == "tcp/[::1]:7447"
    assert client_endpoint("tcp/10.0.0.2:7447") == "tcp/10.0.0.2:7447"


def test_ring_scenario_is_a_valid_scenario() -> None:
    from fleet.sim.scenario import parse_scenario

    scenario = parse_scenario(ring_scenario(5), "ring")
    assert [u.piccolo_id for u in scenario.uavs] == [101, 102, 103, 104, 105]
    assert len({u.alt for u in scenario.uavs}) == 5


@pytest.fixture
def make_fleet(tmp_path: Path) -> Iterator[Callable[..., Fleet]]:
    """Fleets on a free endpoint, logging into tmp_path; none leaves a child behind."""
    fleets: list[Fleet] = []

    def make(
        scenario: str,
        onboard_command: tuple[str, ...],
        start_timeout_s: float,
        speedup: float = 1.0,
        key_space: KeySpace = SPACE,
    ) -> Fleet:
        spec = FleetSpec(
            scenario=scenario,
            listen=ANY_PORT,
            speedup=speedup,
            log_dir=tmp_path,
            start_timeout_s=start_timeout_s,
            onboard_command=onboard_command,
            key_space=key_space,
        )
        fleets.append(Fleet(spec))
        return fleets[-1]

    yield make
    for fleet in fleets:
        for child in fleet.children:
            kill_if_alive(child.pid)


@pytest.mark.e2e
def test_fleet_starts_waits_for_liveliness_and_stops_everything(
    tmp_path: Path, make_fleet: Callable[..., Fleet]
) -> None:
    fleet = make_fleet("head_on", ("-c", FAKE_ONBOARD), start_timeout_s=30.0, speedup=5.0)
    with fleet:
        assert sorted(fleet.uav_ids) == [74, 112]
        assert all(e.program.startswith("socket://127.0.0.1:") for e in fleet.endpoints)
        with zenoh.open(make_config("client", [fleet.connect])) as session:
            tokens = [
                str(r.ok.key_expr)
                for r in session.liveliness().get(SPACE.all_alive, timeout=2.0)
                if r.ok is not None
            ]
        assert sorted(tokens) == ["fleet/uav/112/alive", "fleet/uav/74/alive"]
        pids = [c.pid for c in fleet.children]
        assert len(pids) == 3
    assert all(c.process.returncode is not None for c in fleet.children)
    assert not any(alive(pid) for pid in pids)
    assert "ready" in (tmp_path / "sim.log").read_text()


@pytest.mark.e2e
def test_a_fleet_under_another_prefix_hands_it_to_its_children(
    make_fleet: Callable[..., Fleet],
) -> None:
    lab = KeySpace("lab")
    fleet = make_fleet("head_on", ("-c", FAKE_ONBOARD), 30.0, 5.0, lab)
    with fleet, zenoh.open(make_config("client", [fleet.connect])) as session:
        # Started: the launcher saw them alive with telemetry under lab/.
        tokens = [
            str(r.ok.key_expr)
            for r in session.liveliness().get(lab.all_alive, timeout=2.0)
            if r.ok is not None
        ]
        assert sorted(tokens) == ["lab/uav/112/alive", "lab/uav/74/alive"]


@pytest.mark.e2e
def test_fleet_is_not_ready_until_telemetry_flows(make_fleet: Callable[..., Fleet]) -> None:
    # Alive but silent (no serial link, no telemetry): the start must not report it ready.
    fleet = make_fleet("single_uav", ("-c", FAKE_ONBOARD, "--silent"), start_timeout_s=15.0)
    with (
        pytest.raises(LaunchError, match="telemetry with a GPS fix from UAV 112") as caught,
        fleet,
    ):
        pass
    assert "liveliness" not in str(caught.value)  # it was alive: only telemetry lacked


@pytest.mark.e2e
def test_fleet_reports_an_onboard_that_dies_at_start(make_fleet: Callable[..., Fleet]) -> None:
    dies = ("-c", "import sys; print('no autopilot here', file=sys.stderr); sys.exit(3)")
    fleet = make_fleet("single_uav", dies, start_timeout_s=30.0)
    with pytest.raises(LaunchError, match="exited with status 3") as caught, fleet:
        pass
    assert "no autopilot here" in str(caught.value)
    assert all(c.process.returncode is not None for c in fleet.children)


@pytest.mark.e2e
def test_fleet_up_command_stops_every_child_on_sigterm(tmp_path: Path) -> None:
    endpoint = "tcp/127.0.0.1:0"  # a port the OS picks; the banner says which
    errors = (tmp_path / "up.stderr").open("w")
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "programs.fleet_cli",
            "up",
            "--uavs",
            "2",
            "--listen",
            endpoint,
            "--log-dir",
            str(tmp_path),
            "--start-timeout",
            "60",
        ],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=errors,
        text=True,
    )
    lines: list[str] = []
    banner = threading.Event()

    def read() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)
            if "stops the fleet" in line:
                banner.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    pids: list[int] = []
    try:
        assert banner.wait(70), "".join(lines) + (tmp_path / "up.stderr").read_text()
        pids = [int(line.split()[0]) for line in (tmp_path / "pids").read_text().splitlines()]
        # The fork server, the simulator and two onboards (fleet up records itself).
        assert len(pids) == 4
        text = "".join(lines)
        # The advice names the port bound, where the router is reached.
        advice = re.search(r"export FLEET_ZENOH_CONNECT=(tcp/127\.0\.0\.1:(\d+))\n", text)
        assert advice is not None and int(advice[2]) != 0, text
        assert f"router on {advice[1]}\n" in text
        with zenoh.open(make_config("client", [advice[1]])) as client:
            assert len(list(client.info.routers_zid())) == 1
        assert "101, 102" in text
        # Progress while starting: the simulator first, then the UAVs coming up.
        assert "fleet up: simulator up with 2 aircraft" in text
        assert text.index("simulator up") < text.index("stops the fleet")
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=20) == 0
        reader.join(timeout=5)
        assert "fleet up: stopped" in "".join(lines)
        assert not any(alive(pid) for pid in pids)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        for pid in pids:
            kill_if_alive(pid)
        if process.stdout is not None:
            process.stdout.close()
        errors.close()


def test_fleet_up_refuses_an_unknown_scenario_before_starting_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from programs.fleet_cli import main

    # Guessed free, not port 0: the claim is that nothing listens on the port it was told.
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    status = main(["up", "no_such_scenario", "--listen", endpoint, "--log-dir", str(tmp_path)])
    assert status == 2
    assert "no_such_scenario" in capsys.readouterr().err
    assert not (tmp_path / "pids").exists()
    with pytest.raises(zenoh.ZError, match="Unable to connect"):  # no router was left behind
        zenoh.open(make_config("client", [endpoint])).close()
