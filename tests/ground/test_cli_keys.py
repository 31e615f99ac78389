"""`ground-cli keys` against a real Zenoh router (embedded in the test's process, its
fake UAVs too: tests/ground/conftest.py): the router's own admin space is listed with
the fleet's keys (the rest of `ground-cli` runs on the in-process bus, test_cli.py)."""

from __future__ import annotations

import json

import pytest

from tests.support.fake_onboard import FakeOnboard
from tests.support.ground_cli import ground_cli_here


def test_keys_shows_telemetry_state_and_token(router: str, fakes: dict[int, FakeOnboard]) -> None:
    done = ground_cli_here(
        "keys", "fleet/uav/74/**", "--json", "--window", "0.5", "--admin", connect=router
    )
    assert done.returncode == 0, done.stderr
    found = {item["key"]: item for item in json.loads(done.stdout)}
    telemetry = found["fleet/uav/74/telemetry"]
    assert telemetry["via"] == "subscription"
    assert telemetry["encoding"].startswith("application/json")
    assert telemetry["value"]["gps"]["lat"] == pytest.approx(fakes[74].lat)
    assert found["fleet/uav/74/state"]["value"]["uav"] == 74
    assert found["fleet/uav/74/alive"]["via"] == "liveliness"
    assert not any(key.startswith("fleet/uav/112") for key in found)
    admin = [key for key in found if key.startswith("@/")]
    assert any("/router" in key for key in admin), admin

    text = ground_cli_here("keys", "--window", "0.3", connect=router)
    assert text.returncode == 0, text.stderr
    assert any(line.startswith("fleet/uav/112/telemetry = {") for line in text.stdout.splitlines())


@pytest.mark.parametrize(
    ("expr", "why"),
    [
        ("fleet//uav", "empty chunks are forbidden"),
        ("fleet/uav*", "`*` may only be preceded by `/` or `$`"),
        ("fleet/uav/#", "`#` and `?` are forbidden characters"),
    ],
)
def test_a_bad_key_expression_is_one_line_saying_how_to_write_one(
    router: str, expr: str, why: str
) -> None:
    done = ground_cli_here("keys", expr, "--window", "0", connect=router)
    assert done.returncode == 2 and done.stdout == ""
    [line] = done.stderr.splitlines()  # no traceback, no Rust source path
    assert line.startswith(f"ground-cli: error: {expr!r} is not a key expression ({why}")
    assert line.endswith("(e.g. fleet/** or fleet/uav/*/telemetry)") and ".rs" not in line


def test_an_expression_zenoh_puts_in_canonical_form_is_taken_in_it(
    router: str, fakes: dict[int, FakeOnboard]
) -> None:
    done = ground_cli_here("keys", "fleet/uav/**/**", "--json", "--window", "0.3", connect=router)
    assert done.returncode == 0, done.stderr
    keys = {item["key"] for item in json.loads(done.stdout)}
    assert {"fleet/uav/74/telemetry", "fleet/uav/112/telemetry"} <= keys
