"""`ground-cli watch`: a live table of the fleet with the status box (thesis 3.1.4).

Status messages (`fleet/uav/*/status`) are printed the moment they arrive, each with its
UAV's Piccolo ID, as the thesis's status box listed them; the table of every UAV is
printed every `interval_s`. On a terminal each frame redraws the screen (table, then the
latest status messages); otherwise frames are appended, so the output can be logged.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TextIO

import zenoh

from ground.fleet_view import FleetView, format_table

log = logging.getLogger(__name__)

#: Status lines shown under the table when redrawing a terminal.
STATUS_BOX_LINES = 12
_CLEAR = "\x1b[H\x1b[2J"


def _status_line(when: float, uav: int, text: str) -> str:
    return f"{time.strftime('%H:%M:%S', time.localtime(when))} UAV {uav}: {text}"


def watch(
    session: zenoh.Session,
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

    def on_status(uav: int, text: str) -> None:
        if redraw:
            return  # shown in the status box at the next frame
        with write_lock:
            out.write(_status_line(time.time(), uav, text) + "\n")
            out.flush()

    started = time.monotonic()
    frames = 0
    with FleetView(session, on_status=on_status) as view:
        try:
            while count is None or frames < count:
                view.refresh_states(query_timeout_s)
                frame = format_table(view.snapshot())
                if redraw:
                    box = [_status_line(*s) for s in view.recent_statuses(STATUS_BOX_LINES)]
                    frame = _CLEAR + frame + "\n\nstatus:\n" + "\n".join(box)
                else:
                    stamp = time.strftime("%H:%M:%S")
                    frame = f"-- {stamp} {len(view.live_ids())} UAV(s)\n{frame}"
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
