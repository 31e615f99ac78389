"""What an idle onboard process must not load: the solver stack until a plan is asked
for (onboard.planner.planner_worker builds it lazily), and hashlib or OpenSSL ever (the
consensus digest is fleet.consensus.digest's own SHA-256)."""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.e2e
@pytest.mark.parametrize(
    ("imports", "absent"),
    [
        pytest.param("onboard.process, onboard.main", ("pyomo", "highspy", "numpy"), id="solver"),
        pytest.param(
            "onboard.process, fleet.consensus.replan", ("hashlib", "_hashlib", "_ssl"), id="ssl"
        ),
    ],
)
def test_an_idle_onboard_process_does_not_load(imports: str, absent: tuple[str, ...]) -> None:
    probe = f"import sys, {imports}; print(sorted(m for m in {absent!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "[]"
