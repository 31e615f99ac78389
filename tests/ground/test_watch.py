"""`ground-cli watch`'s status lines, pinned box and terminal frames (the run as a
process, appending, is in test_cli)."""

from __future__ import annotations

import io
import threading
import time

from fleet.mission.key_space import KeySpace
from fleet.mission.messages import StatusText
from fleet.mission.status_kind import StatusKind
from fleet.transport.zenoh_bus import client_bus
from ground.alerts import StatusRecord
from ground.watch import alerts_box, status_line, watch
from tests.support.fake_onboard import FakeOnboard

SPACE = KeySpace()


def test_each_status_line_starts_with_its_severity() -> None:
    assert status_line(StatusRecord(0.0, 74, "reached target 0", StatusKind.INFO)).startswith(
        "info    "
    )
    line = status_line(StatusRecord(0.0, 74, "link slow", StatusKind.WARNING))
    assert line.startswith("warning ") and line.endswith(" UAV 74: link slow")
    assert status_line(StatusRecord(0.0, 7, "x", StatusKind.ERROR)).startswith("error   ")


def test_the_pinned_box_lists_newest_first_and_is_absent_when_empty() -> None:
    assert alerts_box([]) == []
    box = alerts_box(
        [
            StatusRecord(0.0, 1, "old", StatusKind.WARNING),
            StatusRecord(1.0, 2, "new", StatusKind.ERROR),
        ]
    )
    assert box[0] == "warnings and errors (pinned):"
    assert "UAV 2: new" in box[1] and "UAV 1: old" in box[2]


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_terminal_each_frame_redraws_table_pinned_alerts_and_stream(
    router: str, fakes: dict[int, FakeOnboard]
) -> None:
    screen = Terminal()
    with client_bus(router) as session:
        seen = threading.Event()

        def warn_once_watching() -> None:
            # Once the first frame is drawn, watch is subscribed: raise an error then.
            deadline = time.monotonic() + 10.0
            while "\x1b[2J" not in screen.getvalue():
                if time.monotonic() > deadline:
                    return
                time.sleep(0.02)
            fakes[74].put(
                SPACE.status(74), StatusText("error: autopilot link lost", StatusKind.LINK_LOST)
            )
            seen.set()

        thread = threading.Thread(target=warn_once_watching)
        thread.start()
        frames = watch(session, SPACE, screen, count=5, duration_s=None, interval_s=0.3)
        thread.join(10)
    assert frames == 5 and seen.is_set()
    last = screen.getvalue().rsplit("\x1b[H\x1b[2J", 1)[1]
    table, pinned, stream = last.split("\n\n", 2)
    assert table.split()[0] == "ID"
    assert pinned.splitlines()[0] == "warnings and errors (pinned):"
    assert "error" in pinned and "UAV 74: error: autopilot link lost" in pinned
    assert stream.startswith("status:\n")
