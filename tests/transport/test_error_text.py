"""Zenoh's errors in one line a user can act on: no Rust source paths."""

from __future__ import annotations

from fleet.transport.router import listen_problem
from fleet.transport.zenoh_config import error_text

PORT_IN_USE = (
    "Can not create a new TCP listener bound to tcp/127.0.0.1:58831: [127.0.0.1:58831: "
    "Address already in use (os error 98) at /root/.cargo/git/checkouts/zenoh-9c599d5ef3e0480e/"
    "cc83980/io/zenoh-link-commons/src/tcp.rs:61.] at /root/.cargo/git/checkouts/"
    "zenoh-9c599d5ef3e0480e/cc83980/io/zenoh-links/zenoh-link-tcp/src/unicast.rs:338."
)


def test_every_rust_location_goes_nested_or_not() -> None:
    text = error_text(RuntimeError(PORT_IN_USE))
    assert ".rs" not in text and "/root" not in text
    assert text == (
        "Can not create a new TCP listener bound to tcp/127.0.0.1:58831: (127.0.0.1:58831: "
        "Address already in use (os error 98))"
    )
    assert error_text(RuntimeError("Remote resource 3 not found at /x/session.rs:299.")) == (
        "Remote resource 3 not found"
    )


def test_a_port_in_use_says_what_to_do() -> None:
    said = listen_problem(RuntimeError(PORT_IN_USE))
    assert said.startswith("the address is in use") and "stop it" in said
    assert listen_problem(RuntimeError("bad endpoint at /a/b.rs:1.")) == "bad endpoint"
