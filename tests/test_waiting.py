"""A wait's bound is stretched on a loaded machine and left as written on an idle one
(`tests/support/waiting.py`)."""

from __future__ import annotations

import os

import pytest

from tests.support import waiting


@pytest.mark.parametrize(
    ("load", "expected"),
    [(0.1, 10.0), (2.0, 10.0), (6.0, 30.0), (40.0, 10.0 * waiting.MAX_STRETCH)],
)
def test_a_bound_is_stretched_by_the_load_per_core_within_limits(
    monkeypatch: pytest.MonkeyPatch, load: float, expected: float
) -> None:
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (load, 0.0, 0.0))
    assert waiting.stretched(10.0) == pytest.approx(expected)


def test_a_wait_that_times_out_says_how_long_it_waited(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    with pytest.raises(AssertionError, match=r"timed out after 0 s waiting for nothing"):
        waiting.wait_until(lambda: False, 0.1, "nothing")
