"""`ground-cli watch`: a live table of the fleet with the status box (thesis 3.1.4).

Status messages (`fleet/uav/*/status`) are printed the moment they arrive, each with its
severity and its UAV's Piccolo ID, as the thesis's status box listed them; the table of
every UAV is printed every `interval_s`. On a terminal each frame redraws the screen
(table, the pinned warnings and errors, then the latest status messages); otherwise
frames are appended, so the output can be logged, each frame followed by the pinned
warnings and errors. Which alerts stay pinned: `ground.alerts`.

Each frame costs one wildcard state query (`fleet/uav/*/state`), whatever the fleet's
size; everything else arrives by subscription.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TextIO

from fleet.mission.key_space import KeySpace
from fleet.transport.bus import Bus
from ground.alerts import StatusRecord
from ground.fleet_view import FleetView, format_table

log = logging.getLogger(__name__)

#: Status lines shown under the table when redrawing a terminal.
STATUS_BOX_LINES = 12
_CLEAR = "\x1b[H\x1b[2J"


def status_line(status: StatusRecord) -> str:
    """`warning 12:00:01 UAV 74: text`: the severity first, padded to one width."""
    when = time.strftime("%H:%M:%S", time.localtime(status.time))
    return f"{status.severity:<7} {when} UAV {status.uav}: {status.text}"


def alerts_box(alerts: list[StatusRecord]) -> list[str]:
    """The pinned warnings and errors, newest first, under their own heading."""
    if not alerts:
        return []
    return ["warnings and errors (pinned):", *("  " + status_line(a) for a in reversed(alerts))]


def watch(
    bus: Bus,
    space: KeySpace,
    out: TextIO,
    *,
    count: int | None,
    duration_s: float | None,
    interval_s: float = 1.0,
    query_timeout_s: float = 0.5,
) -> int:
    """Run until `count` frames were shown or `duration_s` passed (or Ctrl-C).

    Returns the number of frames shown.
    """
    redraw = out.isatty()
    write_lock = threading.Lock()

    def on_status(status: StatusRecord) -> None:
        if redraw:
            return  # shown in the status box at the next frame
        with write_lock:
            out.write(status_line(status) + "\n")
            out.flush()

    started = time.monotonic()
    frames = 0
    with FleetView(bus, space, on_status=on_status) as view:
        try:
            while count is None or frames < count:
                view.refresh_states(query_timeout_s)
                frame = format_table(view.snapshot())
                pinned = alerts_box(view.alerts())
                if redraw:
                    box = [status_line(s) for s in view.recent_records(STATUS_BOX_LINES)]
                    frame = "\n\n".join([_CLEAR + frame, *(["\n".join(pinned)] if pinned else [])])
                    frame += "\n\nstatus:\n" + "\n".join(box)
                else:
                    stamp = time.strftime("%H:%M:%S")
                    frame = "\n".join([f"-- {stamp} {len(view.live_ids())} UAV(s)", frame, *pinned])
                with write_lock:
                    out.write(frame + "\n")
                    out.flush()
                frames += 1
                if count is not None and frames >= count:
                    break
                elapsed = time.monotonic() - started
                if duration_s is not None and elapsed >= duration_s:
                    break
                pause = interval_s
                if duration_s is not None:
                    pause = min(pause, duration_s - elapsed)
                time.sleep(max(0.0, pause))
        except KeyboardInterrupt:
            log.debug("watch interrupted")
    return frames
