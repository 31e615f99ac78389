"""`ground-cli watch`'s status lines and pinned box (the end-to-end run is in test_cli)."""

from __future__ import annotations

from fleet.mission.phase import Severity
from ground.alerts import StatusRecord
from ground.watch import alerts_box, status_line


def test_each_status_line_starts_with_its_severity() -> None:
    assert status_line(StatusRecord(0.0, 74, "reached target 0", Severity.INFO)).startswith(
        "info    "
    )
    line = status_line(StatusRecord(0.0, 74, "link slow", Severity.WARNING))
    assert line.startswith("warning ") and line.endswith(" UAV 74: link slow")
    assert status_line(StatusRecord(0.0, 7, "x", Severity.ERROR)).startswith("error   ")


def test_the_pinned_box_lists_newest_first_and_is_absent_when_empty() -> None:
    assert alerts_box([]) == []
    box = alerts_box(
        [StatusRecord(0.0, 1, "old", Severity.WARNING), StatusRecord(1.0, 2, "new", Severity.ERROR)]
    )
    assert box[0] == "warnings and errors (pinned):"
    assert "UAV 2: new" in box[1] and "UAV 1: old" in box[2]
