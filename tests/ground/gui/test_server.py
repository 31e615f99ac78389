"""`ground-cli gui`: the HTTP API, the WebSocket's snapshots and commands, and its access
rules, against the page served in the test's process on the in-process bus with two
fake UAVs; what only a process shows (its argv, its output, SIGTERM) against
`ground-cli gui` as a real subprocess and a real router."""

from __future__ import annotations

import asyncio
import json
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from fleet.mission.messages import MISSION_MANAGER, Target
from fleet.mission.targets_file import encode_targets
from fleet.transport.bus_factory import opened_bus
from ground.propose import DEFAULT_WINDOW_S, named_proposers
from tests.ground.test_cli import run_cli
from tests.support.fake_onboard import FakeOnboard, fake_pair
from tests.support.gui_page import serving, websocket_url
from tests.support.processes import ANY_PAGE, Child, start
from tests.support.waiting import wait_until

TARGETS = [Target(42.36, -71.09, 120.0), Target(42.365, -71.1, 110.0)]
TOKEN = "s3cret-token"


def start_gui(router: str, *extra: str, env: dict[str, str] | None = None) -> tuple[Child, str]:
    """`ground-cli gui` on a free port: its process and the page's URL it printed
    (without the trailing slash)."""
    child = start(
        "ground-cli gui",
        [sys.executable, "-m", "ground.cli", "--connect", router, "gui",
         "--listen", ANY_PAGE, *extra],
        env=env,
    )  # fmt: skip
    serving = child.wait_for_line(lambda line: line.startswith("gui: serving on"), 30.0)
    return child, serving.removeprefix("gui: serving on ").split()[0].rstrip("/")


@pytest.fixture(scope="module")
def memory(memory_router: str) -> str:
    """The fleet's bus for the page served in this process: an in-process one."""
    return memory_router


@pytest.fixture(scope="module")
def mfakes(memory: str) -> Iterator[dict[int, FakeOnboard]]:
    with fake_pair(memory) as pair:
        yield pair


@pytest.fixture(scope="module")
def gui(memory: str, mfakes: dict[int, FakeOnboard]) -> Iterator[str]:
    with opened_bus(memory) as bus, serving(bus) as url:
        yield url


def ws_url(page: str) -> str:
    """The page's WebSocket, with the session token only the page served holds."""
    return websocket_url(page)


def get(url: str, headers: dict[str, str] | None = None) -> tuple[int, Any]:
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


def post(url: str, body: bytes) -> tuple[int, bytes]:
    request = urllib.request.Request(url, data=body, method="POST")
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()


def test_api_fleet_is_what_uavs_json_says(gui: str, memory: str) -> None:
    def both_known() -> bool:
        status, page = get(f"{gui}/api/fleet")
        assert status == 200
        return [row["id"] for row in page] == [74, 112] and all(
            row["enabled"] is not None for row in page
        )

    # A live view: the UAVs' tokens, telemetry and first state answers fill it in.
    assert wait_until(both_known, 10.0)
    _, page = get(f"{gui}/api/fleet")
    cli = run_cli("uavs", "--json", endpoint=memory)
    assert cli.returncode == 0, cli.stderr
    expected = json.loads(cli.stdout)
    assert [row["id"] for row in page] == [row["id"] for row in expected] == [74, 112]
    for mine, theirs in zip(page, expected, strict=True):
        assert mine.keys() == theirs.keys()
        assert (mine["lat"], mine["lon"], mine["enabled"]) == (
            theirs["lat"],
            theirs["lon"],
            theirs["enabled"],
        )


def test_load_refuses_a_malformed_file_and_save_writes_every_format(gui: str) -> None:
    status, body = post(f"{gui}/api/targets/import?name=bad.bin", b"\x00" * 25)
    assert status == 400
    assert "bad.bin: target 1 at byte offset 24" in json.loads(body)["error"]
    status, body = post(f"{gui}/api/targets/import?name=t.bin", encode_targets(TARGETS))
    assert status == 200 and len(json.loads(body)["targets"]) == 2
    targets = json.dumps([{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]).encode()
    status, body = post(f"{gui}/api/targets/export?format=csv", targets)
    assert status == 200 and body.decode().splitlines()[0] == "lat,lon,alt"
    status, body = post(f"{gui}/api/targets/export?format=bin", targets)
    assert status == 200 and body == encode_targets(TARGETS)
    status, body = post(f"{gui}/api/targets/export?format=kml", targets)
    assert status == 400 and b"kml" in body


def test_a_deeply_nested_geojson_upload_is_a_clear_400(gui: str) -> None:
    deep = b'{"type": "FeatureCollection", "features": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    status, body = post(f"{gui}/api/targets/import?name=deep.geojson", deep)
    assert status == 400
    error = json.loads(body)["error"]
    assert "deep.geojson" in error and "Traceback" not in error


async def _session_with(url: str, commands: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Connects, sends each command and collects its reply; returns the replies."""
    replies = []
    async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(url)) as ws:
        first = await ws.receive_json(timeout=10)
        assert first["type"] == "snapshot"
        assert [uav["id"] for uav in first["uavs"]] == [74, 112]
        for command in commands:
            await ws.send_str(json.dumps(command))
            while (message := await ws.receive_json(timeout=20))["type"] != "reply":
                pass
            replies.append(message)
    return replies


def test_send_and_abort_from_the_websocket(gui: str, mfakes: dict[int, FakeOnboard]) -> None:
    fakes = mfakes
    targets: list[dict[str, float]] = [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]
    before = len(fakes[74].targets)
    malformed, empty_team, bad_target, sent = asyncio.run(
        _session_with(
            gui,
            [
                {"cmd": "send", "id": 1, "team": "74", "targets": targets},
                {"cmd": "send", "id": 2, "team": [], "targets": targets},
                {
                    "cmd": "send",
                    "id": 3,
                    "team": [74],
                    "targets": [{"lat": 91, "lon": 0, "alt": 0}],
                },
                {"cmd": "send", "id": 4, "team": [74, 112], "targets": targets},
            ],
        )
    )
    assert not malformed["ok"] and "malformed command" in malformed["message"]
    assert not empty_team["ok"] and "no team" in empty_team["message"]
    assert not bad_target["ok"] and "target 0: latitude 91" in bad_target["message"]
    assert sent["ok"] and "2 targets published to 74, 112" in sent["message"]
    assert wait_until(lambda: len(fakes[74].targets) == before + 1)
    mission = fakes[74].targets[-1].mission
    assert wait_until(lambda: get(f"{gui}/api/mission")[1].get("complete") is True, 10.0)
    _, outcome = get(f"{gui}/api/mission")
    assert outcome["mission"] == mission and outcome["team"] == [74, 112]
    assert outcome["agreed"] is True and sorted(outcome["assignment"]) == ["112", "74"]

    (aborted,) = asyncio.run(_session_with(gui, [{"cmd": "abort", "id": 5}]))
    assert aborted["ok"] and f"mission {mission}: abort sent" in aborted["message"]
    assert wait_until(lambda: any(a.mission == mission for a in fakes[112].aborts))


def test_opm_from_the_websocket_and_its_confirmation_in_the_snapshot(
    gui: str, mfakes: dict[int, FakeOnboard]
) -> None:
    fakes = mfakes

    async def scenario() -> tuple[dict[str, Any], list[dict[str, Any]]]:
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(gui)) as ws:
            await ws.send_str(json.dumps({"cmd": "opm", "id": 9, "uav": 112, "enabled": False}))
            reply = None
            statuses: list[dict[str, Any]] = []
            while reply is None or not any("module off" in s["text"] for s in statuses):
                message = await ws.receive_json(timeout=10)
                if message["type"] == "reply":
                    reply = message
                else:
                    statuses += message["statuses"]
            return reply, statuses

    reply, statuses = asyncio.run(scenario())
    assert reply["ok"] and "UAV 112: planning module off sent" in reply["message"]
    status = next(s for s in statuses if "module off" in s["text"])
    assert status["uav"] == 112 and status["severity"] == "info"
    assert wait_until(lambda: fakes[112].opms and fakes[112].opms[-1].enabled is False)
    fakes[112].enabled = True


def test_a_binary_message_is_refused_and_the_socket_kept(gui: str) -> None:
    async def scenario() -> tuple[dict[str, Any], dict[str, Any]]:
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(gui)) as ws:
            await ws.send_bytes(b"\x00\x01")
            while (refused := await ws.receive_json(timeout=10))["type"] != "reply":
                pass
            await ws.send_str("not json")
            while (malformed := await ws.receive_json(timeout=10))["type"] != "reply":
                pass
            return refused, malformed

    refused, malformed = asyncio.run(scenario())
    assert not refused["ok"] and "commands are JSON text" in refused["message"]
    assert not malformed["ok"] and "malformed command" in malformed["message"]


def test_a_websocket_from_another_origin_is_refused(gui: str) -> None:
    async def scenario() -> int:
        async with aiohttp.ClientSession() as http:
            try:
                async with http.ws_connect(ws_url(gui), origin="http://evil.example"):
                    return 101
            except aiohttp.WSServerHandshakeError as error:
                return error.status

    assert asyncio.run(scenario()) == 403


def test_a_dns_rebinding_page_is_refused(gui: str) -> None:
    port = gui.rsplit(":", 1)[1]
    rebound = {"Host": f"evil.example:{port}"}  # another site's name, this address
    for path in ("/", "/api/fleet", "/api/mission", "/static/app.js"):
        status, answer = get(f"{gui}{path}", rebound)
        assert status == 403 and "host" in answer["error"], path
    # The operator's own names for the page work.
    assert get(f"{gui}/api/fleet", {"Host": f"localhost:{port}"})[0] == 200
    assert get(f"{gui}/api/fleet")[0] == 200


def test_a_websocket_without_the_pages_session_token_is_refused(gui: str) -> None:
    async def status_of(url: str, **kwargs: Any) -> int:
        async with aiohttp.ClientSession() as http:
            try:
                async with http.ws_connect(url, **kwargs) as ws:
                    await ws.receive_json(timeout=10)  # the first snapshot
                    return 101
            except aiohttp.WSServerHandshakeError as error:
                return error.status

    same_origin = {"origin": gui}
    assert asyncio.run(status_of(f"{gui}/ws", **same_origin)) == 403
    assert asyncio.run(status_of(f"{gui}/ws?session=guess", **same_origin)) == 403
    assert asyncio.run(status_of(ws_url(gui), **same_origin)) == 101

    async def refused_counts() -> dict[str, Any]:
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(gui)) as ws:
            snapshot: dict[str, Any] = await ws.receive_json(timeout=10)
            refused: dict[str, Any] = snapshot["refused"]
            return refused

    refused = asyncio.run(refused_counts())  # counted, and shown to the page
    assert refused["requests"] >= 2 and isinstance(refused["bus"], dict)
    # The cookie the page sets: this host only, never sent to another site.
    with urllib.request.urlopen(f"{gui}/", timeout=10) as response:
        cookie = response.headers["Set-Cookie"]
    assert "fleet_gui_session=" in cookie and "SameSite=Strict" in cookie
    assert "HttpOnly" in cookie


def test_a_change_in_flight_not_acknowledged_fails_with_who_did_not(
    gui: str, mfakes: dict[int, FakeOnboard]
) -> None:
    """The fakes commit every mission as first sent (revision 0): a change put to them is
    never acknowledged, and the page's command fails saying by whom; a bad index, a
    target out of range, or a proposal for the greedy is refused with nothing sent."""
    targets: list[dict[str, float]] = [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]
    added = [{"lat": 42.36, "lon": -71.095, "alt": 120.0}]
    (sent,) = asyncio.run(
        _session_with(gui, [{"cmd": "send", "id": 20, "team": [74, 112], "targets": targets}])
    )
    assert sent["ok"], sent
    mission = sent["mission"]
    assert wait_until(
        lambda: len(mfakes[112].targets) and mfakes[112].targets[-1].mission == mission
    )
    before = len(mfakes[74].targets)
    unacked, beyond, bad, greedy = asyncio.run(
        _session_with(
            gui,
            [
                {"cmd": "add-targets", "id": 21, "targets": added, "wait_s": 1.0},
                {"cmd": "remove-targets", "id": 22, "indexes": [7], "wait_s": 1.0},
                {"cmd": "add-targets", "id": 23, "targets": [{"lat": 91, "lon": 0, "alt": 0}]},
                {"cmd": "send", "id": 24, "team": [74], "targets": targets, "propose": True},
            ],
        )
    )
    assert not unacked["ok"] and unacked["mission"] == mission
    assert f"mission {mission} revision 1: target 2 added" in unacked["message"]
    assert "not acknowledged by 74, 112 within 1 s" in unacked["message"]
    # The revision was put (the fakes heard it): the page shows its target.
    assert wait_until(lambda: mfakes[74].targets[-1].revision == 1)
    assert not beyond["ok"] and "target 7 is not one of the mission's 3" in beyond["message"]
    assert "nothing sent" in beyond["message"]
    assert not bad["ok"] and "target 3: latitude 91" in bad["message"]
    assert not greedy["ok"] and "min-sum or min-max" in greedy["message"]
    assert "nothing sent" in greedy["message"]
    assert len(mfakes[74].targets) == before + 1  # the unacknowledged revision alone
    _, outcome = get(f"{gui}/api/mission")
    assert outcome["mission"] == mission and len(outcome["targets"]) == 3


def test_the_page_names_uav_proposers_as_send_targets_does(
    gui: str, mfakes: dict[int, FakeOnboard]
) -> None:
    """The page's "UAV proposers" field names the UAVs that propose (`send-targets
    --proposers`, through the same `named_proposers`): the mission put names them with
    the proposal window; a proposer outside the team, or one for the greedy, is refused
    with nothing sent."""
    targets: list[dict[str, float]] = [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]
    send = {"cmd": "send", "team": [74, 112], "targets": targets, "objective": "min-max"}
    before = len(mfakes[112].targets)
    named, outside, greedy = asyncio.run(
        _session_with(
            gui,
            [
                {**send, "id": 40, "proposers": [112]},
                {**send, "id": 41, "proposers": [74, 300]},
                {**send, "id": 42, "proposers": [74], "objective": "greedy"},
            ],
        )
    )
    assert named["ok"] and "UAV 112 to propose a plan" in named["message"], named
    assert wait_until(lambda: len(mfakes[112].targets) > before)
    heard = mfakes[112].targets[-1]
    assert heard.mission == named["mission"] and heard.proposers == (112,)
    assert heard.proposals_s == DEFAULT_WINDOW_S and heard.deadline_s > DEFAULT_WINDOW_S
    assert not outside["ok"] and "UAV proposer 300 is not in the team" in outside["message"]
    assert not greedy["ok"] and "min-sum or min-max" in greedy["message"]
    assert "nothing sent" in outside["message"] and "nothing sent" in greedy["message"]
    assert len(mfakes[112].targets) == before + 1
    # With the ground proposing too, it is named after the UAVs, as by send-targets.
    assert named_proposers(True, (112, 74, 112), (74, 112)) == (112, 74, MISSION_MANAGER)
    assert named_proposers(True, (), (74, 112)) == ()


def test_an_abort_is_not_held_up_by_a_change_waiting_for_acknowledgements(
    gui: str, mfakes: dict[int, FakeOnboard]
) -> None:
    """A change is put in its turn and its acknowledgements awaited after it: an Abort
    pressed meanwhile is answered (and on the bus) before the change's reply."""
    targets: list[dict[str, float]] = [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]
    (sent,) = asyncio.run(
        _session_with(gui, [{"cmd": "send", "id": 30, "team": [74, 112], "targets": targets}])
    )
    mission = sent["mission"]
    assert wait_until(lambda: mfakes[74].targets[-1].mission == mission)

    async def scenario() -> list[dict[str, Any]]:
        async with aiohttp.ClientSession() as http, http.ws_connect(ws_url(gui)) as ws:
            change = {"cmd": "remove-targets", "id": "c-1", "indexes": [1], "wait_s": 5.0}
            await ws.send_str(json.dumps(change))
            await ws.send_str(json.dumps({"cmd": "abort", "id": "c-2"}))
            replies: list[dict[str, Any]] = []
            while len(replies) < 2:
                message = await ws.receive_json(timeout=20)
                if message["type"] == "reply":
                    replies.append(message)
            return replies

    first, second = asyncio.run(scenario())
    assert (first["id"], second["id"]) == ("c-2", "c-1")
    assert first["ok"] and f"mission {mission}: abort sent" in first["message"]
    assert not second["ok"] and "not acknowledged by 74, 112 within 5 s" in second["message"]
    # Both went out: the revision (put in its turn) and the abort.
    assert [t.revision for t in mfakes[74].targets[-1:]] == [1]
    assert any(a.mission == mission for a in mfakes[74].aborts)


@pytest.mark.e2e
def test_a_token_when_given_guards_every_request(
    router: str, fakes: object, tmp_path: Path
) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN + "\n")
    token_file.chmod(0o600)
    child, url = start_gui(router, "--token-file", str(token_file))
    try:
        assert get(f"{url}/api/fleet")[0] == 401
        assert get(f"{url}/api/fleet?token=wrong")[0] == 401
        assert get(f"{url}/api/fleet?token={TOKEN}")[0] == 200
        assert get(f"{url}/api/fleet", {"Authorization": f"Bearer {TOKEN}"})[0] == 200
    finally:
        assert child.stop() == 0
    # Never printed: not with the URL, not in the log (the child's stdout and stderr).
    assert not any(TOKEN in line for line in child.history), child.history
    assert any(str(token_file) in line for line in child.history)


@pytest.mark.e2e
def test_the_token_is_never_argv_and_a_made_one_is_never_printed(
    router: str, fakes: object, tmp_path: Path
) -> None:
    done = run_cli("gui", "--token", TOKEN, endpoint=router)
    assert done.returncode == 2 and "--token-file" in done.stderr and "ps" in done.stderr
    # From the environment: enforced, and not printed either.
    child, url = start_gui(router, env={"FLEET_GUI_TOKEN": TOKEN})
    try:
        assert get(f"{url}/api/fleet")[0] == 401
        assert get(f"{url}/api/fleet?token={TOKEN}")[0] == 200
    finally:
        assert child.stop() == 0
    assert not any(TOKEN in line for line in child.history), child.history
    # A token file that does not exist yet: a new token, owner-only, in it and nowhere else.
    made = tmp_path / "made-token"
    child, url = start_gui(router, "--token-file", str(made))
    try:
        token = made.read_text().strip()
        assert len(token) >= 24 and made.stat().st_mode & 0o077 == 0
        assert get(f"{url}/api/fleet")[0] == 401
        assert get(f"{url}/api/fleet?token={token}")[0] == 200
    finally:
        assert child.stop() == 0
    assert not any(token in line for line in child.history), child.history


def test_listening_beyond_loopback_needs_allow_remote() -> None:
    done = run_cli("gui", "--listen", "0.0.0.0:8321", endpoint=None)
    assert done.returncode == 2
    assert "not loopback" in done.stderr and "--allow-remote" in done.stderr


@pytest.mark.e2e
def test_sigterm_with_a_page_open_closes_its_socket_as_going_away(
    router: str, fakes: dict[int, FakeOnboard]
) -> None:
    child, url = start_gui(router)

    async def open_page_then_stop() -> tuple[int | None, int]:
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(ws_url(url), origin=url) as ws,
        ):
            await ws.receive_json()  # the first snapshot: the page is open
            child.process.terminate()
            closing = (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING)
            for _ in range(10_000):  # snapshots until the close (bounded)
                if (await ws.receive()).type in closing:
                    break
            return ws.close_code, await asyncio.to_thread(child.process.wait, 60)

    try:
        code, status = asyncio.run(open_page_then_stop())
    finally:
        child.stop()
    # Told it is going away at once, not left until the server's shutdown time-out.
    assert code == aiohttp.WSCloseCode.GOING_AWAY
    assert status == 0
