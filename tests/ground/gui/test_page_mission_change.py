"""The page's mission changes and proposed plan against three real onboards in memory
(tests/support/memory_world.py), through the page's own WebSocket as a browser uses it:
Send with "propose a plan" (the ground solves with PyVRP, as `send-targets --propose`),
the proposal's adoption shown as the UAVs' reported digests say; every proposal heard
(a UAV's solved on board too, and one put under a name the mission does not entitle)
shown with its score and the digests' verdict; targets added and one
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
import msgspec
import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MISSION_MANAGER, PlanProposal
from fleet.transport.bus import BusSample, decode_sample
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
#: Twelve targets on which PyVRP's plan beat the baseline in runs of the test (the
#: adopted one is then UAV 101's: tied with the ground's, the lower Piccolo ID wins).
PROPOSED = ring_targets(12, seed=1)


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


def test_the_page_shows_each_proposal_heard_and_whether_the_team_adopted_it(
    tmp_path: Path,
) -> None:
    """UAV 101 proposes on board and the ground too (the page's "UAV proposers" and
    "propose a plan"): the page shows each proposal heard with its proposer, its score
    (the UAVs' scorer, run on the team's results) and the verdict the UAVs' reported
    digests give; a copy of 101's plan put under UAV 102's name, which the mission does
    not entitle, is shown refused and never adopted."""
    with memory_fleet(ring_file(tmp_path, 3), proposers=frozenset({101})) as fleet:
        team = sorted(fleet.ids)
        bus = fleet.bus()
        heard = AssignmentsHeard(bus, SPACE)
        forged: list[PlanProposal] = []

        def forge(sample: BusSample) -> None:
            proposal = decode_sample(sample, PlanProposal)
            if proposal is not None and proposal.proposer == 101 and not forged:
                forged.append(msgspec.structs.replace(proposal, proposer=102))
                bus.publish(SPACE.uav_proposal(proposal.mission, 102), forged[0])

        bus.subscribe(SPACE.all_uav_proposals, forge)
        with serving(fleet.bus()) as url:

            async def scenario() -> dict[str, Any]:
                async with (
                    aiohttp.ClientSession() as http,
                    http.ws_connect(websocket_url(url)) as ws,
                ):
                    page = Page(ws)
                    sent = await page.command(
                        {"cmd": "send", "id": "q-1", "team": team, "targets": as_json(PROPOSED),
                         "objective": "min-max", "propose": True, "proposers": [101]}
                    )  # fmt: skip
                    assert sent["ok"], sent

                    def judged(m: dict[str, Any]) -> bool:
                        proposals = m.get("proposals") or {}
                        shown = {p["proposer"]: p for p in proposals.get("heard", [])}
                        return (
                            m["complete"]
                            and {101, 102, MISSION_MANAGER} <= shown.keys()
                            and all(p["verdict"] != "waiting" for p in shown.values())
                            and len(proposals.get("plans", [])) == 1
                        )

                    shown = await page.until("every proposal judged", judged)
                    async with http.get(f"{url}/api/mission") as response:
                        shown["api"] = await response.json()
                    return shown

            shown = asyncio.run(scenario())
    reports = heard.latest()
    (digest,) = {reports[uav].digest for uav in team}
    proposals = shown["proposals"]
    assert (
        proposals["named"] == [101, MISSION_MANAGER]
        and proposals["not_heard"] == []
        and proposals["declined"] == []
    )
    (plan,) = proposals["plans"]
    assert plan["digest"] == digest and plan["by"] == team
    # `/api/mission` carries the same verdicts, as `send-targets --json` does.
    api = shown["api"]
    heard_by = {p["proposer"]: p["verdict"] for p in proposals["heard"]}
    assert api["uav_proposals"]["101"]["verdict"] == heard_by[101]
    assert api["proposal"]["verdict"] == heard_by[MISSION_MANAGER]
    by = {p["proposer"]: p for p in proposals["heard"]}
    assert by[101]["by"] == "UAV 101" and by[MISSION_MANAGER]["by"] == "the ground"
    # The verdict is the UAVs' digests': adopted by every UAV when their one digest is the
    # proposal's own, else not adopted: the baseline kept, or the other proposal taken.
    key = 0  # min-max: the last arrival first
    for proposer in (101, MISSION_MANAGER):
        seen = by[proposer]
        assert seen["check"] == "valid" and seen["score"] is not None, seen
        figures = (seen["score"]["makespan_s"], seen["score"]["total_s"])
        committed = (plan["score"]["makespan_s"], plan["score"]["total_s"])
        if seen["adopted_digest"] == digest:
            assert (seen["verdict"], seen["adopted_by"]) == ("adopted", team)
            # The score shown is what the UAVs adopting it reported.
            assert figures == pytest.approx(committed, abs=0.11)
        elif seen["baseline_digest"] == digest:
            assert (seen["verdict"], seen["baseline_by"]) == ("baseline", team)
        else:
            assert (seen["verdict"], seen["other_by"]) == ("other", team)
            (instead,) = seen["instead"]
            assert instead["adopted_by"] == team
            assert by[instead["proposer"]]["adopted_digest"] == digest
        # The team adopts the best: no valid proposal scores better than what it took.
        assert figures[key] >= committed[key] - 0.11
    assert shown["proposal"]["verdict"] == by[MISSION_MANAGER]["verdict"]
    assert shown["proposal"]["score"] == by[MISSION_MANAGER]["score"]
    # The copy under 102's name: the UAVs refuse it, and the page never says adopted.
    assert forged
    copy = by[102]
    assert copy["check"] == "refused" and copy["score"] is None
    assert "102 is not among the mission's proposers (101, 65534)" in copy["problem"]
    assert copy["verdict"] != "adopted" and digest != copy["adopted_digest"]
