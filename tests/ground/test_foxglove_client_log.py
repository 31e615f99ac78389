"""A Foxglove client leaving without the closing handshake is logged as INFO, not ERROR."""

from __future__ import annotations

import logging

import pytest

from ground.foxglove_live.client_log import POLLER, quiet_client_resets


def test_a_client_gone_without_a_closing_handshake_is_info_other_errors_stay(
    caplog: pytest.LogCaptureFixture,
) -> None:
    quiet_client_resets()
    quiet_client_resets()  # once is enough: no second filter
    logger = logging.getLogger(POLLER)
    assert len(logger.filters) == 1
    with caplog.at_level(logging.INFO, logger=POLLER):
        logger.error(
            "Error receiving from client 127.0.0.1:45950: WebSocket protocol error: "
            "Connection reset without closing handshake"
        )
        logger.error("Error receiving from client 127.0.0.1:45950: invalid frame")
    assert [r.levelname for r in caplog.records] == ["INFO", "ERROR"]
