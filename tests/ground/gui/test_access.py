"""The page's Host allow-list and session token (`ground.gui.access`)."""

from __future__ import annotations

import pytest

from ground.gui.access import Access


@pytest.mark.parametrize(
    ("bound", "host", "allowed"),
    [
        ("127.0.0.1", "127.0.0.1", True),
        ("127.0.0.1", "localhost", True),
        ("127.0.0.1", "LOCALHOST.", True),
        ("127.0.0.1", "::1", True),
        ("127.0.0.1", "evil.example", False),
        ("127.0.0.1", "127.0.0.1.evil.example", False),
        ("127.0.0.1", None, False),
        ("localhost", "127.0.0.1", True),
        ("::1", "[::1]", True),
        ("192.168.1.5", "192.168.1.5", True),
        ("192.168.1.5", "127.0.0.1", False),
        ("192.168.1.5", "evil.example", False),
        ("0.0.0.0", "anything.example", True),  # every interface: the token guards it
    ],
)
def test_the_host_allow_list(bound: str, host: str | None, allowed: bool) -> None:
    assert Access(bound).host_allowed(host) is allowed


def test_the_session_token_is_per_run_and_in_the_served_page() -> None:
    first, second = Access("127.0.0.1"), Access("127.0.0.1")
    assert first.session != second.session and len(first.session) >= 32
    assert first.session_matches(first.session)
    assert not first.session_matches(second.session) and not first.session_matches("")
    html = first.with_session("<html><head><title>x</title></head></html>")
    assert f'<head>\n<meta name="fleet-session" content="{first.session}">' in html
