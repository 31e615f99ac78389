"""`fleet foxglove` seen by a third-party Foxglove client, end to end.

Real processes throughout: `fleet up head_on` (router, simulator, two onboards),
`fleet record` and `fleet foxglove` on its router, `ground-cli send-targets`, and the
`@foxglove/ws-protocol` client from npm under node (tests/js/foxglove_client.mjs), which
decodes what the server advertises with protobufjs and JSON.parse, never with the
project's code. A Zenoh subscriber in the test is the bus observer the client's
LocationFix messages are compared with.
"""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from importlib.resources import files
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh
from mcap.reader import make_reader

from fleet.files.certs import write_identities
from fleet.launch.children import stop_children
from fleet.mission.key_space import KeySpace, uav_id_of
from fleet.recording.recorder import READY_LINE as RECORD_READY
from ground.foxglove_live.command import READY_LINE as FOXGLOVE_READY
from tests.support.ground_cli import ground_cli
from tests.support.processes import ANY_PORT, Child, client_session, start, wait_fleet_up
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

SPACE = KeySpace()
TEAM = {74, 112}
FLEET = [sys.executable, "-m", "programs.fleet_cli"]
JS = Path(__file__).resolve().parents[1] / "js"
#: 60 fixes in a row may all be one UAV's: in the secure profile a UAV's telemetry is
#: released in bursts, a signed digest's worth at a time (half a second: about 50 samples
#: at --speedup 5, more when a loaded machine delays a digest), and a loaded machine can
#: stall one UAV's telemetry for a second in either profile. 600 are about 3 s of both
#: UAVs' telemetry: as long as a sample waits for its digest before it is dropped.
FIXES = 600
TIMEOUT_S = 120.0


def node_client(url: str, *args: str) -> Child:
    """The third-party client on `url`; its output is JSON lines (see the script)."""
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.fail("needs node and npm (.ci/run installs them where missing)")
    if not (JS / "node_modules" / "@foxglove").is_dir():
        # The README's test command alone installs the client too, at the versions the
        # lock file pins (what .ci/run does before the tests).
        install = ["npm", "ci", "--prefix", str(JS), "--no-audit", "--no-fund"]
        done = subprocess.run(install, capture_output=True, text=True, timeout=300, check=False)
        if done.returncode != 0:
            pytest.fail(f"`{' '.join(install)}` failed: {done.stderr[-2000:]}")
    return start("foxglove client", ["node", str(JS / "foxglove_client.mjs"), url, *args])


def fleet_up(tmp_path: Path, listen: str, *extra: str) -> tuple[Child, str]:
    """`fleet up head_on` listening on `listen`, once its UAVs are up: its process and
    the endpoint it said it listens on."""
    up = start(
        "fleet up",
        [*FLEET, "up", "head_on", "--listen", listen, "--no-record",
         "--log-dir", str(tmp_path / "run"), *extra],
    )  # fmt: skip
    try:
        endpoint = wait_fleet_up(up, 90.0).connect
    except AssertionError:
        stop_children([up], 10.0)
        raise
    return up, endpoint


def serve(endpoint: str, *extra: str) -> tuple[Child, str]:
    """`fleet foxglove` on the fleet at `endpoint`, and the URL it serves."""
    fox = start("fleet foxglove", [*FLEET, "foxglove", "--serve", "127.0.0.1:0",
                                   "--connect", endpoint, *extra])  # fmt: skip
    ready = fox.wait_for_line(lambda line: line.startswith(FOXGLOVE_READY), 30.0)
    url = re.search(r"ws://\S+", ready)
    assert url is not None, ready
    return fox, url[0]


def events(child: Child, kind: str) -> list[dict[str, Any]]:
    found = []
    for line in list(child.history):
        if line.startswith("{"):
            event: dict[str, Any] = json.loads(line)
            if event["event"] == kind:
                found.append(event)
    return found


def uav_phases(endpoint: str) -> dict[int, str]:
    done = ground_cli("uavs", "--json", connect=endpoint, timeout=TIMEOUT_S)
    assert done.returncode == 0, done.stderr
    return {view["id"]: view["phase"] for view in json.loads(done.stdout)}


def recorded_topics(path: Path, since_ns: int) -> tuple[dict[str, str], set[str]]:
    """Each topic of the recording with its schema name, and the topics heard only
    before `since_ns` (a live server started then could not have heard them)."""
    topics: dict[str, str] = {}
    last_ns: dict[str, int] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            topics[channel.topic] = schema.name if schema is not None else ""
            last_ns[channel.topic] = max(last_ns.get(channel.topic, 0), message.log_time)
    return topics, {topic for topic, at in last_ns.items() if at < since_ns}


class BusObserver:
    """Every position each UAV's telemetry put on the bus."""

    def __init__(self, session: zenoh.Session) -> None:
        self.positions: dict[int, set[tuple[float, float, float]]] = {uav: set() for uav in TEAM}
        self._lock = threading.Lock()
        self._subscriber = session.declare_subscriber(SPACE.all_telemetry, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        gps = msgspec.json.decode(sample.payload.to_bytes()).get("gps")
        if gps is not None:
            with self._lock:
                self.positions.setdefault(uav_id_of(str(sample.key_expr)), set()).add(
                    (gps["lat"], gps["lon"], gps["alt"])
                )

    def saw(self, uav: int, position: tuple[float, float, float]) -> bool:
        with self._lock:
            return position in self.positions.get(uav, set())


def check_fixes(client: Child, observer: BusObserver | None, count: int = FIXES) -> None:
    """Each LocationFix the client decoded is a position the UAV published, for each UAV."""
    assert client.process.wait(TIMEOUT_S) == 0, "\n".join(client.history[-10:])
    assert events(client, "open")[0]["protocol"] == "foxglove.sdk.v1"
    info = events(client, "serverInfo")[0]
    assert info["name"] == "uav-fleet"
    # Read-only: Foxglove can neither publish to the fleet nor call a service.
    assert not {"clientPublish", "services"} & set(info["capabilities"])
    fixes = events(client, "message")
    assert len(fixes) == count
    seen: set[int] = set()
    for event in fixes:
        fix = event["message"]
        assert event["schemaName"] == "foxglove.LocationFix"
        uav = int(fix["frameId"].removeprefix("uav"))
        assert event["topic"] == f"fleet/uav/{uav}/location_fix"
        position = (fix["latitude"], fix["longitude"], fix["altitude"])
        if observer is not None:
            wait_until(
                lambda: observer.saw(uav, position),  # noqa: B023
                10.0,
                f"UAV {uav} at {position} on the bus",
            )
        seen.add(uav)
    assert seen == TEAM


def reached_on_the_map(client: Child) -> bool:
    """Whether the latest GeoJSON says targets 0 and 1 were reached."""
    maps = events(client, "message")
    if not maps:
        return False
    collection = json.loads(maps[-1]["message"]["geojson"])
    states = {
        f["properties"]["target"]: f["properties"]["state"]
        for f in collection["features"]
        if f["geometry"]["type"] == "Point"
    }
    return states.get(0) == states.get(1) == "reached"


def scene_complete(client: Child) -> bool:
    """Whether the latest SceneUpdate holds both UAVs (arrows), the mission's three
    targets (spheres), and nothing but in the frame `fleet`, after deleting all."""
    updates = [
        e["message"] for e in events(client, "message") if e["schemaName"] == "foxglove.SceneUpdate"
    ]
    if not updates:
        return False
    latest = updates[-1]
    found = {entity["id"]: entity for entity in latest["entities"]}
    uavs = {f"uav/{uav}" for uav in TEAM}
    targets = {f"target/1/{index}" for index in range(3)}
    if not uavs | targets <= set(found):
        return False
    assert all(entity["frameId"] == "fleet" for entity in latest["entities"])
    assert all(len(found[uav]["arrows"]) == 1 for uav in uavs)
    assert all(len(found[target]["spheres"]) == 1 for target in targets)
    assert latest["deletions"][0]["type"] == 1  # ALL: the scene is replaced whole
    return True


def check_logs(client: Child) -> None:
    """The UAVs' status texts came as foxglove.Log, each named for its UAV."""
    logs = [e["message"] for e in events(client, "message") if e["schemaName"] == "foxglove.Log"]
    assert logs, "no status text on the Log topic"
    assert {log["name"] for log in logs} <= {f"uav{uav}" for uav in TEAM}
    assert all(log["message"] and log["level"] in (2, 3, 4) for log in logs)


def test_a_foxglove_client_sees_the_fleet_as_the_bus_and_the_recorder_do(tmp_path: Path) -> None:
    up, endpoint = fleet_up(tmp_path, ANY_PORT, "--speedup", "10")
    children: list[Child] = []
    try:
        with client_session(endpoint) as session:
            observer = BusObserver(session)
            record = start("fleet record", [*FLEET, "record", str(tmp_path / "rec.mcap"),
                                            "--connect", endpoint])  # fmt: skip
            children.append(record)
            record.wait_for_line(lambda line: line.startswith(RECORD_READY), 30.0)
            fox, url = serve(endpoint)
            children.append(fox)
            live_since_ns = time.time_ns()  # it subscribed before saying it serves
            # Advertisements only (subscribed to nothing), until stopped.
            topics = node_client(url, "--topics", "^$", "--count", "0")
            children.append(topics)
            # Both UAVs' telemetry flowing first; then enough fixes to span a stall of
            # either (a loaded machine can hold one UAV's telemetry for a second, while
            # 60 fixes at --speedup 10 are a third of a second of the other's).
            wait_until(lambda: all(observer.positions.get(uav) for uav in TEAM), 60.0,
                       "both UAVs' telemetry on the bus")  # fmt: skip
            fixes = node_client(url, "--topics", "/location_fix$", "--count", str(FIXES))
            children.append(fixes)
            check_fixes(fixes, observer)

            # A mission: its targets, assignment and arrivals on the map, in 3D, and what
            # the UAVs said on the Log panel's topic.
            the_map = node_client(url, "--topics", "/map/targets$", "--count", "0")
            children.append(the_map)
            scene_and_log = node_client(url, "--topics", "^fleet/(scene|log)$", "--count", "0")
            children.append(scene_and_log)
            targets = str(files("fleet") / "scenarios" / "head_on_targets.bin")
            sent = ground_cli(
                "send-targets", targets, "--wait", connect=endpoint, timeout=TIMEOUT_S
            )
            assert sent.returncode == 0, sent.stdout + sent.stderr
            wait_until(
                lambda: set(uav_phases(endpoint).values()) == {"reached"}, 150.0, "both reached"
            )
            wait_until(lambda: reached_on_the_map(the_map), 30.0, "the map to show both reached")
            wait_until(lambda: scene_complete(scene_and_log), 30.0, "the 3D scene of the mission")
            check_logs(scene_and_log)
            # Stopped together, so that both heard the same keys.
            stop_children([record, fox], 10.0)
            assert record.process.returncode == 0, "\n".join(record.history[-10:])
            assert fox.process.returncode == 0, "\n".join(fox.history[-10:])
            # Its clients left (each node client exits without a closing handshake, as a
            # closed tab does): news, not errors.
            assert not [line for line in fox.history if " ERROR " in line], fox.history[-10:]
    finally:
        stop_children([*reversed(children), up], 10.0)

    live = {e["topic"]: e["schemaName"] for e in events(topics, "advertise")}
    recorded, before_live = recorded_topics(tmp_path / "rec.mcap", live_since_ns)
    # The recorder started first: a key put only before the live server started is
    # excused. In practice only the tokens are (heard once, when they appeared), and the
    # live server has them too, from the tokens' history.
    missing = set(recorded) - set(live) - before_live
    assert not missing, f"recorded, never served live: {sorted(missing)}"
    assert {f"fleet/uav/{uav}/alive" for uav in TEAM} <= set(live)
    assert live == {
        **{t: name for t, name in recorded.items() if t in live},
        "fleet/map/targets": "foxglove.GeoJSON",
        "fleet/scene": "foxglove.SceneUpdate",
        "fleet/log": "foxglove.Log",
    }
    assert {f"fleet/uav/{uav}/location_fix" for uav in TEAM} <= set(live)
    assert {"fleet/mission/1/targets", "fleet/uav/74/state", "fleet/uav/112/status"} <= set(live)


def test_in_the_secure_profile_it_holds_the_grounds_identity(tmp_path: Path) -> None:
    certs = tmp_path / "certs"
    listen = "tls/127.0.0.1:0"  # the certificates name the host; the port is any free one
    write_identities(certs, ["router", "ground", "uav-74", "uav-112"], [listen])
    up, endpoint = fleet_up(tmp_path, listen, "--secure", str(certs), "--speedup", "5")
    children: list[Child] = []
    try:
        fox, url = serve(endpoint, "--zenoh-config", str(certs / "ground.json5"))
        children.append(fox)
        fixes = node_client(url, "--topics", "/location_fix$", "--count", str(FIXES))
        children.append(fixes)
        check_fixes(fixes, None)
        # The state is served to the ground's identity only: it is queried and shown.
        state = node_client(url, "--topics", "/state$", "--count", "2")
        children.append(state)
        assert state.process.wait(TIMEOUT_S) == 0, "\n".join(state.history[-10:])
        assert {e["message"]["uav"] for e in events(state, "message")} <= TEAM
    finally:
        stop_children([*reversed(children), up], 10.0)


def test_a_web_page_of_another_origin_or_host_is_refused_and_foxglove_is_not(router: str) -> None:
    """Any web page in the operator's browser could open ws://127.0.0.1:8765 (browsers
    let every site connect anywhere, with the page's Origin): the server refuses a
    foreign Origin or Host, and serves Foxglove's own clients (no Origin, or its app's)."""
    fox, url = serve(router)
    children: list[Child] = [fox]
    try:
        evil = node_client(url, "--origin", "https://evil.example", "--count", "1")
        children.append(evil)
        assert evil.process.wait(TIMEOUT_S) == 1
        assert "403" in events(evil, "error")[0]["error"]
        assert not events(evil, "serverInfo")
        for extra in ([], ["--origin", "https://app.foxglove.dev"]):
            client = node_client(url, "--topics", "^$", "--count", "0", *extra)
            children.append(client)
            client.wait_for_line(lambda line: '"serverInfo"' in line, TIMEOUT_S)
        # DNS rebinding: the attacker's name for this address, with its own origin.
        port = int(url.rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port), timeout=10) as raw:
            raw.sendall(
                b"GET / HTTP/1.1\r\nHost: rebind.evil.example:%d\r\nUpgrade: websocket\r\n"
                b"Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                b"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
                % port
            )
            answer = raw.recv(4096)
        assert answer.startswith(b"HTTP/1.1 403") and b"host" in answer
        stop_children(list(reversed(children)), 10.0)
    finally:
        stop_children(list(reversed(children)), 10.0)
    assert fox.process.returncode == 0, fox.history[-10:]
    assert not any("Traceback" in line for line in fox.history), fox.history
    said = [line for line in fox.history if "refused 2 client(s)" in line]
    assert said and "'origin': 1" in said[0] and "'host': 1" in said[0], fox.history[-3:]
