"""What the team committed to, as the tests of `send-targets` read it: each UAV's latest
`AssignmentReport` heard on the bus, and the check that every UAV agrees on one plan
and that the command's JSON says it."""

from __future__ import annotations

import threading
from typing import Any

import pytest

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import AssignmentReport
from fleet.transport.bus import Bus, BusSample, decode_sample


class AssignmentsHeard:
    """Each UAV's latest `AssignmentReport` on `bus` since it was made (any thread)."""

    def __init__(self, bus: Bus, space: KeySpace) -> None:
        self._lock = threading.Lock()
        self._latest: dict[int, AssignmentReport] = {}
        bus.subscribe(f"{space.prefix}/mission/*/assignment/*", self._on_assignment)

    def _on_assignment(self, sample: BusSample) -> None:
        report = decode_sample(sample, AssignmentReport)
        if report is not None:
            with self._lock:
                self._latest[report.uav] = report

    def latest(self) -> dict[int, AssignmentReport]:
        with self._lock:
            return dict(self._latest)


def assert_one_plan(
    report: dict[str, Any], reports: dict[int, AssignmentReport], n_targets: int
) -> None:
    """Every UAV's commitment in `reports` is one plan of `n_targets`, and `send-targets
    --json`'s `report` says it target by target."""
    first = next(iter(reports.values()))
    # Every UAV agrees: one digest, the same queues, every target in exactly one queue.
    assert len({(r.digest, str(r.queues)) for r in reports.values()}) == 1
    queued = [t for q in first.queues.values() for t in q]
    assert sorted(queued) == list(range(n_targets))
    # The JSON tells each target its holder, its place in that queue and its arrival.
    for state in report["target_states"]:
        holder = state["uav"]
        queue = first.queues[holder]
        assert state["place"] == queue.index(state["index"]) + 1
        assert state["eta_s"] == pytest.approx(first.arrivals[holder][state["place"] - 1])
