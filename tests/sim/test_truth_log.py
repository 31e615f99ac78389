"""The simulator's truth log: written every period, read back, a pass between two samples
counted at its true closest distance."""

from __future__ import annotations

import io

from fleet.geo.mercator import MercatorProjection
from fleet.sim.truth_log import TruthLog, closest_approaches, read_truth

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
