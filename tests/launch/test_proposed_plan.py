"""A proposed plan, end to end: `fleet up windy` (router, simulator, three onboards),
twenty targets, min-max, `ground-cli send-targets --propose` solving the queues with
PyVRP once the results are in, and a rogue client putting an invalid proposal (a target
twice, other results, from a lower ID) throughout. Every UAV commits one plan with one
digest: the ground's proposal where the deterministic scorer finds it strictly better
than the baseline (here it is: PyVRP's bisection beats the baseline's min-max on this
instance, about 8 % when measured), else the baseline, both recomputed here from the
recorded results; the invalid one refused by each UAV (its log says why). Then UAV 201,
started with `fleet up --proposers 201`, proposes the next mission's plan itself (named
by `send-targets --proposers 201`), signed as 201 on its own key: every UAV commits one
digest, the plan adopted from 201's proposal or the baseline, as the ground reads it."""

from __future__ import annotations

import json
import random
import signal
import threading
from pathlib import Path

import msgspec
import pytest

from fleet.consensus.mission_round import MissionRound
from fleet.consensus.objectives import plan_digest
from fleet.consensus.proposal import plan_key, proposal_digest
from fleet.consensus.queues import finish
from fleet.mission.key_space import DEFAULT_SPACE
from fleet.mission.messages import MissionTargets, PlanProposal, UavResult
from fleet.mission.objective import Objective
from fleet.recording.reader import read_recording
from fleet.transport.zenoh_bus import client_bus
from tests.support.ground_cli import ground_cli
from tests.support.processes import ANY_PORT, start_fleet_up, wait_fleet_up
from tests.support.targets import targets_csv

pytest.importorskip("pyvrp", reason="PyVRP is not installed: pip install '.[solver]'")
pytestmark = pytest.mark.e2e

MISSION = 41
#: The mission UAV 201 proposes for, and the UAV.
UAV_MISSION, PROPOSER = 42, 201
#: Twenty targets, local metres east/north of the windy scenario's origin, seeded.
_RNG = random.Random(35)
POINTS = [(_RNG.uniform(-6000, 6000), _RNG.uniform(-9000, 12000)) for _ in range(20)]


def _rogue(endpoint: str, stop: threading.Event) -> None:
    """Put an invalid proposal for the mission every 0.2 s until `stop`."""
    bad = PlanProposal(
        mission=MISSION,
        proposer=1,
        digest="0" * 16,
        objective=Objective.MIN_MAX,
        queues={201: (0, 0, *range(1, 8)), 202: tuple(range(8, 14)), 203: tuple(range(14, 20))},
    )
    with client_bus(endpoint) as bus:
        while not stop.wait(0.2):
            bus.publish(DEFAULT_SPACE.uav_proposal(MISSION, 1), bad)


def test_a_proposed_plan_is_verified_and_one_plan_adopted_by_every_uav(tmp_path: Path) -> None:
    up = start_fleet_up(
        "windy", "--listen", ANY_PORT, "--speedup", "3", "--log-dir", str(tmp_path),
        "--proposers", str(PROPOSER),
    )  # fmt: skip
    stop = threading.Event()
    try:
        endpoint = wait_fleet_up(up, 90.0).connect
        rogue = threading.Thread(target=_rogue, args=(endpoint, stop), daemon=True)
        rogue.start()
        csv_file = targets_csv(tmp_path / "nine.csv", (35.72, -120.76), POINTS)
        sent = ground_cli(
            "send-targets", str(csv_file), "--objective", "min-max",
            "--propose", "--mission", str(MISSION), "--wait", "--json", "--timeout", "90",
            connect=endpoint, timeout=240,
        )  # fmt: skip
        assert sent.returncode == 0, sent.stderr[-3000:]
        outcome = json.loads(sent.stdout)
        assert outcome["agreed"] is True, sent.stderr[-3000:]
        assert "plan proposed" in sent.stderr, sent.stderr[-3000:]
        by_uav = ground_cli(
            "send-targets", str(csv_file), "--objective", "min-max",
            "--proposers", str(PROPOSER), "--mission", str(UAV_MISSION),
            "--wait", "--json", "--timeout", "90",
            connect=endpoint, timeout=240,
        )  # fmt: skip
        assert by_uav.returncode == 0, by_uav.stderr[-3000:]
        uav_outcome = json.loads(by_uav.stdout)
        assert uav_outcome["agreed"] is True, by_uav.stderr[-3000:]
    finally:
        stop.set()
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(60) == 0
    recording = read_recording(tmp_path / "fleet.mcap")
    results: dict[int, UavResult] = {}
    reports = {}
    proposal = targets = None
    for message in recording.messages:
        if f"mission/{MISSION}/result/" in message.topic:
            result = msgspec.json.decode(message.data, type=UavResult)
            results[result.uav] = result
        elif message.topic.endswith(f"mission/{MISSION}/targets"):
            targets = msgspec.json.decode(message.data, type=MissionTargets)
        elif message.topic.endswith(f"mission/{MISSION}/proposal"):
            heard = msgspec.json.decode(message.data, type=PlanProposal)
            if heard.proposer != 1:
                proposal = heard
        elif f"mission/{MISSION}/assignment/" in message.topic:
            reports[message.topic] = message.value()
    assert targets is not None and proposal is not None and len(reports) == 3
    # One plan, one digest, on every UAV.
    assert len({(r["digest"], json.dumps(r["queues"])) for r in reports.values()}) == 1
    committed = next(iter(reports.values()))
    # What each UAV computed: the baseline from the recorded results, then the choice.
    mission_round = MissionRound(
        targets=msgspec.structs.replace(targets, proposals_s=0.0), own_id=201, started=0.0
    )
    for result in results.values():
        assert mission_round.add_result(result)
    used = {uav: r.times for uav, r in mission_round.results.items()}
    legs = mission_round.air_legs(used)
    baseline = mission_round.decide(set(used))
    base_key = plan_key(
        finish({u: list(q) for u, q in baseline.queues.items()}, used, legs), Objective.MIN_MAX
    )
    proposed_key = plan_key(
        finish({u: list(q) for u, q in proposal.queues.items()}, used, legs), Objective.MIN_MAX
    )
    if proposed_key < base_key:
        inputs = mission_round.results_digest(used)
        expected = proposal_digest(plan_digest(inputs, Objective.MIN_MAX), proposal)
        assert committed["digest"] == expected
        assert {int(u): tuple(q) for u, q in committed["queues"].items()} == {
            u: q for u, q in proposal.queues.items() if q
        }
        verdict = "adopted"
    else:
        assert committed["digest"] == baseline.digest
        verdict = "baseline"
    # send-targets says so, from the digests the UAVs reported.
    said = outcome["proposal"]
    assert (said["verdict"], said[f"{verdict}_by"]) == (verdict, [201, 202, 203])
    assert said[f"{verdict}_digest"] == committed["digest"]
    assert "the ground's proposal: " in sent.stderr
    # The rogue's proposal was refused by every UAV.
    for uav in (201, 202, 203):
        log = (tmp_path / f"onboard-{uav}.log").read_text()
        assert "the plan proposed by 1 refused" in log, uav
    # Mission 41 named no UAV proposer: 201 proposed nothing for it.
    assert not [m for m in recording.messages if m.topic.endswith(f"{MISSION}/proposal/201")]
    # Mission 42: UAV 201's own proposal, heard by every UAV, one digest on every UAV.
    own = [
        msgspec.json.decode(m.data, type=PlanProposal)
        for m in recording.messages
        if m.topic.endswith(f"mission/{UAV_MISSION}/proposal/{PROPOSER}")
    ]
    assert own and {p.proposer for p in own} == {PROPOSER}
    second = {
        m.topic: m.value()
        for m in recording.messages
        if f"mission/{UAV_MISSION}/assignment/" in m.topic
    }
    assert len(second) == 3 and len({r["digest"] for r in second.values()}) == 1
    said = uav_outcome["uav_proposals"][str(PROPOSER)]
    assert said["verdict"] in ("adopted", "baseline"), said
    assert said[f"{said['verdict']}_by"] == [201, 202, 203], said
    assert said[f"{said['verdict']}_digest"] == next(iter(second.values()))["digest"]
    assert f"UAV {PROPOSER}'s proposal: " in by_uav.stderr
