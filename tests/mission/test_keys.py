"""The key prefix is one setting ($FLEET_KEY_PREFIX) for every tool."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fleet.mission import keys

SHOW = "from fleet.mission import keys; print(keys.telemetry(7), keys.ALL_ALIVE)"


def _python(code: str, prefix: str | None) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != keys.PREFIX_ENV}
    if prefix is not None:
        env[keys.PREFIX_ENV] = prefix
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60
    )


@pytest.mark.e2e
def test_the_default_prefix_is_fleet() -> None:
    assert _python(SHOW, None).stdout.split() == ["fleet/uav/7/telemetry", "fleet/uav/*/alive"]


@pytest.mark.e2e
def test_the_prefix_comes_from_the_environment() -> None:
    done = _python(SHOW, "replay")
    assert done.stdout.split() == ["replay/uav/7/telemetry", "replay/uav/*/alive"]


@pytest.mark.e2e
def test_a_bad_prefix_is_refused_with_the_reason() -> None:
    done = _python(SHOW, "a/b")
    assert done.returncode != 0 and "one key chunk" in done.stderr


@pytest.mark.parametrize("bad", ["", "a/b", "x*", "**"])
def test_checked_prefix_refuses_anything_but_one_chunk(bad: str) -> None:
    with pytest.raises(ValueError, match="one key chunk"):
        keys.checked_prefix(bad)


def test_use_prefix_rederives_every_wildcard() -> None:
    try:
        keys.use_prefix("replay")
        assert keys.ALL_ALIVE == "replay/uav/*/alive"
        assert keys.ALL_MISSION_ASSIGNMENTS == "replay/mission/*/assignment/*"
        assert keys.ALL_MISSION_REPLANS == "replay/mission/*/replan/*"
        assert keys.mission_targets(3) == "replay/mission/3/targets"
        with pytest.raises(ValueError, match="one key chunk"):
            keys.use_prefix("re/play")
        assert keys.PREFIX == "replay"
    finally:
        keys.use_prefix(keys.DEFAULT_PREFIX)
