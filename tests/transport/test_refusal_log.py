"""`RefusalLog`: a burst of lines at once, then at most that many per period."""

from __future__ import annotations

import logging

import pytest

from fleet.transport.refusal_log import RefusalLog


def test_a_flood_is_logged_a_burst_per_period_with_what_was_left_out(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = [100.0]
    monkeypatch.setattr("fleet.transport.refusal_log.time.monotonic", lambda: clock[0])
    refusals = RefusalLog(logging.getLogger("test.refusals"), every_s=10.0, burst=3)
    with caplog.at_level(logging.WARNING, "test.refusals"):
        logged = [refusals.warn(f"refused {i}") for i in range(10_000)]
        clock[0] += 10.0
        assert refusals.warn("refused 10000")
    assert logged[:4] == [True, True, True, False] and sum(logged) == 3
    assert [r.getMessage() for r in caplog.records] == [
        "refused 0",
        "refused 1",
        "refused 2",
        "refused 10000 (9997 more refused and not logged before this)",
    ]
