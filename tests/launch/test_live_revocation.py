"""Revoking a flying UAV on a running `fleet up --secure`: the router embedded in `fleet
up` closes that onboard's session (a real onboard process, which then keeps dialling)
within seconds, and UAV 112 flies on and keeps reporting, with no restart. The same
through a router-per-UAV mesh: tests/launch/test_router_per_uav.py."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleet.mission.key_space import KeySpace
from tests.support import secure_clients
from tests.support.processes import wait_fleet_up
from tests.support.secure_fleet import start_secure_up
from tests.support.telemetry_times import TelemetryTimes
from tests.support.waiting import wait_until

pytestmark = pytest.mark.e2e

SPACE = KeySpace()
#: Telemetry samples of 112 heard after 74's last: 74's stream has stopped by then.
AFTER = 20


def test_a_revoked_uavs_onboard_is_cut_off_and_its_teammate_flies_on(tmp_path: Path) -> None:
    certs = tmp_path.resolve()
    up = start_secure_up(certs)
    try:
        endpoint = wait_fleet_up(up, 90.0).connect
        with secure_clients.session(certs, endpoint, "ground") as ground:
            telemetry = TelemetryTimes(ground, SPACE)
            wait_until(lambda: telemetry.since(74, 0.0) and telemetry.since(112, 0.0), 60.0,
                       "both UAVs' telemetry")  # fmt: skip
            revoked = subprocess.run(
                [sys.executable, "-m", "programs.fleet_cli", "certs", "revoke", str(certs),
                 "uav-74", "--connect", endpoint],
                capture_output=True, text=True, timeout=120, check=False,
            )  # fmt: skip
            assert revoked.returncode == 0, revoked.stderr[-3000:]
            since = time.monotonic()
            # 74's stream stops while 112's flows (on the code before, 74's kept coming).
            wait_until(lambda: telemetry.stopped(74, 112, since, AFTER), 60.0,
                       "74's telemetry to stop while 112's flows")  # fmt: skip
            # `fleet up`'s log says so.
            up.wait_for_line(lambda line: "refused links so far:" in line and "revoked=" in line,
                             30.0)  # fmt: skip
            stopped_at = telemetry.last(74)

            def reconnections_refused() -> bool:
                shown = secure_clients.ground_cli(certs, endpoint, "routers")
                counted = re.search(r"revoked=(\d+)", shown.stdout)
                return counted is not None and int(counted[1]) >= 2

            # 74's onboard dials again; the router holds that link, then closes it.
            wait_until(reconnections_refused, 60.0, "74's reconnection refused")
            mark = time.monotonic()
            wait_until(lambda: telemetry.since(112, mark) >= AFTER, 30.0, "112's telemetry")
            assert telemetry.last(74) == stopped_at, "74's telemetry came back"
            telemetry.undeclare()
    finally:
        up.process.send_signal(signal.SIGTERM)
        assert up.process.wait(30) == 0
