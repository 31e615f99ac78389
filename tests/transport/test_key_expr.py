"""A key expression a user typed, checked before a session declares it: one line saying
what is wrong, or the expression in Zenoh's canonical form."""

from __future__ import annotations

import pytest
import zenoh

from fleet.transport.key_expr import HOW_TO_WRITE, KeyExprError, checked_key_expr
from fleet.transport.memory import MemoryNetwork


@pytest.mark.parametrize("text", ["fleet/**", "fleet/uav/*/telemetry", "@/**", "fleet/$*x"])
def test_a_canonical_expression_is_kept(text: str) -> None:
    assert checked_key_expr(text) == text


@pytest.mark.parametrize(
    ("text", "canonical"), [("fleet/**/**", "fleet/**"), ("fleet/**/*", "fleet/*/**")]
)
def test_an_expression_zenoh_can_canonize_is_taken_canonized(text: str, canonical: str) -> None:
    assert checked_key_expr(text) == canonical


@pytest.mark.parametrize("text", ["", "fleet/", "/fleet", "fleet//x", "a*b", "fleet/x?y=1"])
def test_a_bad_expression_says_why_and_how_without_rust_paths(text: str) -> None:
    with pytest.raises(KeyExprError) as refused:
        checked_key_expr(text)
    said = str(refused.value)
    assert said.startswith(f"{text!r} is not a key expression (") and said.endswith(HOW_TO_WRITE)
    assert "\n" not in said and ".rs" not in said and "Invalid Key Expr" not in said


def test_the_memory_bus_refuses_a_bad_expression_where_zenoh_does() -> None:
    bus = MemoryNetwork().bus()
    with pytest.raises(zenoh.ZError):
        bus.subscribe("fleet//x", lambda sample: None)
    with pytest.raises(zenoh.ZError):
        bus.declare_queryable("fleet/a*b")
    with pytest.raises(zenoh.ZError):
        bus.query("fleet/", 0.01)
    with pytest.raises(zenoh.ZError):
        bus.live_tokens("fleet/#", 0.01)
