"""The page's mission changes and proposed plan against three real onboards in memory
(tests/support/memory_world.py), through the page's own WebSocket as a browser uses it:
Send with "propose a plan" (the ground solves with PyVRP, as `send-targets --propose`),
the proposal's adoption shown as the UAVs' reported digests say; targets added and one
removed in flight, each answered only once every UAV planned the new revision, and the
page's mission showing it, and a change made by another ground's CLI. The same in a
real browser against a real fleet is tests/ground/gui/test_browser.py."""

from __future__ import annotations

import asyncio
import io
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from fleet.mission.key_space import KeySpace
from fleet.transport.cli import ExitCode
from ground.mission_change_command import AddOptions, run_add_targets
from tests.support.agreement import AssignmentsHeard
from tests.support.gui_page import serving, websocket_url
from tests.support.memory_world import memory_fleet, ring_file
from tests.support.targets import ring_targets

pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")

SPACE = KeySpace()
TARGETS = ring_targets(9, seed=35)
FIRST, LATER = TARGETS[:7], TARGETS[7:]


def as_json(targets: Any) -> list[dict[str, float]]:
    return [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in targets]


class Page:
    """One WebSocket of the page: commands with their replies, and the latest snapshot."""

    def __init__(self, ws: aiohttp.ClientWebSocketResponse) -> None:
        self.ws = ws
        self.snapshot: dict[str, Any] = {}
        self.replies: dict[Any, dict[str, Any]] = {}

    async def read_one(self) -> None:
        message = await self.ws.receive_json(timeout=30)
        if message["type"] == "snapshot":
            self.snapshot = message
        elif message["type"] == "reply":
            self.replies[message["id"]] = message

    async def command(self, body: dict[str, Any]) -> dict[str, Any]:
        await self.ws.send_str(json.dumps(body))
        while body["id"] not in self.replies:
            await self.read_one()
        return self.replies[body["id"]]

    async def until(self, what: str, holds: Callable[[dict[str, Any]], bool]) -> dict[str, Any]:
        """The first snapshot's mission for which `holds` (60 s at most)."""

        async def wait() -> dict[str, Any]:
            while not (self.snapshot.get("mission") and holds(self.snapshot["mission"])):
                await self.read_one()
            return dict(self.snapshot["mission"])

        try:
            return await asyncio.wait_for(wait(), 60.0)
        except TimeoutError:
            raise AssertionError(f"never {what}: {self.snapshot.get('mission')}") from None


def test_the_page_proposes_a_plan_then_adds_and_removes_targets_in_flight(
    tmp_path: Path,
) -> None:
    with memory_fleet(ring_file(tmp_path, 3)) as fleet:
        team = sorted(fleet.ids)
        bus = fleet.bus()
        heard = AssignmentsHeard(bus, SPACE)
        with serving(fleet.bus()) as url:

            async def scenario() -> None:
                async with (
                    aiohttp.ClientSession() as http,
                    http.ws_connect(websocket_url(url)) as ws,
                ):
                    page = Page(ws)
                    sent = await page.command(
                        {"cmd": "send", "id": "p-1", "team": team, "targets": as_json(FIRST),
                         "objective": "min-max", "propose": True}
                    )  # fmt: skip
                    assert sent["ok"], sent
                    assert "the ground proposes a plan" in sent["message"]
                    mission = sent["mission"]
                    shown = await page.until(
                        "the proposal's verdict",
                        lambda m: (
                            (m.get("proposal") or {}).get("verdict") in ("adopted", "baseline")
                            and m["complete"]
                        ),
                    )
                    proposal = shown["proposal"]
                    assert proposal["state"] == "proposed by the ground"
                    assert proposal["proposer"] == 0xFFFE and proposal["cpu_s"] >= 0
                    # What the page says is what every UAV reported: one digest, the
                    # proposal's adopted one or the baseline's.
                    reports = heard.latest()
                    digests = {reports[uav].digest for uav in team}
                    verdict = proposal["verdict"]
                    assert digests == {proposal[f"{verdict}_digest"]}
                    assert proposal[f"{verdict}_by"] == team
                    assert shown["agreed"] is True and shown["digest"] in digests

                    added = await page.command(
                        {"cmd": "add-targets", "id": "p-2", "mission": mission,
                         "targets": as_json(LATER)}
                    )  # fmt: skip
                    assert added["ok"], added
                    assert f"mission {mission} revision 1: targets 7, 8 added" in added["message"]
                    assert f"acknowledged by {', '.join(map(str, team))}" in added["message"]
                    latest = heard.latest()
                    assert {latest[uav].revision for uav in team} == {1}
                    queued = sorted(t for q in latest[team[0]].queues.values() for t in q)
                    assert 7 in queued and 8 in queued
                    await page.until("nine targets", lambda m: len(m["target_states"]) == 9)

                    removed = await page.command(
                        {"cmd": "remove-targets", "id": "p-3", "indexes": [8]}
                    )
                    assert removed["ok"], removed
                    assert "revision 2: target 8 removed" in removed["message"]
                    latest = heard.latest()
                    assert {latest[uav].revision for uav in team} == {2}
                    assert all(8 not in q for q in latest[team[0]].queues.values())
                    # The target shows removed from the mission's revision, the revision
                    # from the UAVs' plans of it (each solved from fresh times).
                    shown = await page.until(
                        "target 8 removed, planned at revision 2",
                        lambda m: (
                            m["target_states"][8]["state"] == "removed" and m["revision"] == 2
                        ),
                    )
                    assert shown["removed"] == [8]

                    again = await page.command(
                        {"cmd": "remove-targets", "id": "p-4", "indexes": [8]}
                    )
                    assert not again["ok"] and "target 8 was removed already" in again["message"]
                    assert {heard.latest()[uav].revision for uav in team} == {2}

                    # A change another ground makes (`ground-cli add-targets`) is shown too.
                    options = AddOptions(targets=LATER[:1], mission=mission, json=True)
                    code = await asyncio.to_thread(run_add_targets, bus, options, io.StringIO())
                    assert code == ExitCode.OK
                    shown = await page.until("revision 3", lambda m: m["revision"] == 3)
                    assert len(shown["target_states"]) == 10 and shown["removed"] == [8]

            asyncio.run(scenario())
