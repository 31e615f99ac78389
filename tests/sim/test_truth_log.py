"""The simulator's truth log: written every period, read back, a pass between two samples
counted at its true closest distance."""

from __future__ import annotations

import io
import math
from pathlib import Path

from fleet.geo.mercator import MercatorProjection
from fleet.sim.server import SimServer
from fleet.sim.truth_log import TRUTH_PERIOD_MS, TruthLog, closest_approaches, read_truth
from tests.sim.test_server import HEAD_ON, autopilot_for

ORIGIN = (47.0, 8.0)


def test_samples_are_written_once_a_period_and_read_back() -> None:
    out = io.StringIO()
    log = TruthLog(out, period_ms=200)
    for ms in range(0, 1000, 20):
        log.note(101, ms, (47.0 + ms * 1e-7, 8.0, 300.0))
    samples = read_truth(out.getvalue().splitlines())
    assert [s.sim_ms for s in samples] == [0, 200, 400, 600, 800]
    assert samples[2].lat == 47.00004 and samples[2].alt == 300.0


def test_a_partial_line_is_dropped() -> None:
    samples = read_truth(["sim_ms,uav,lat,lon,alt", "0,101,47.0,8.0,300.0", "200,101,47.0"])
    assert len(samples) == 1


def test_a_pass_between_two_samples_counts_at_its_closest() -> None:
    projection = MercatorProjection(*ORIGIN)
    out = io.StringIO()
    log = TruthLog(out, period_ms=1)
    # Two samples 400 m apart, west and east of a target 30 m north of their midpoint.
    for ms, x in ((0, -200.0), (1, 200.0)):
        log.note(102, ms, (*projection.to_latlon(x, 0.0), 300.0))
    target = projection.to_latlon(0.0, 30.0)
    far = projection.to_latlon(0.0, 500.0)
    nearest = closest_approaches(read_truth(out.getvalue().splitlines()), [target, far])
    assert abs(nearest[102][0] - 30.0) < 0.5
    assert abs(nearest[102][1] - 500.0) < 0.5


def test_the_server_logs_each_aircraft_where_its_own_state_puts_it(tmp_path: Path) -> None:
    """The log the simulator writes is its aircraft's own state, every period, closed with
    the server."""
    path = tmp_path / "truth.csv"
    autopilots = [autopilot_for(HEAD_ON, 0), autopilot_for(HEAD_ON, 1)]
    with SimServer(autopilots, program_port=0, payload_port=0, ground_port=0,
                   speedup=0.0, truth=TruthLog.to_file(str(path))) as server:  # fmt: skip
        server.open()
        server.run(duration=0.2)
        last = {a.piccolo_id: (a.time_ms, a.position()) for a in autopilots}
    samples = read_truth(path.read_text().splitlines())
    for uav, (time_ms, (lat, lon, _)) in last.items():
        own = [s for s in samples if s.uav == uav]
        assert [s.sim_ms for s in own] == list(range(20, time_ms + 1, TRUTH_PERIOD_MS))
        # The last sample is at most one period behind where the aircraft stopped.
        assert math.hypot(*MercatorProjection(lat, lon).to_xy(own[-1].lat, own[-1].lon)) < 10.0
