"""A Foxglove client leaving is news, not an error.

The SDK logs a client that drops its socket without the WebSocket closing handshake (a
browser tab closed or reloaded, a script that exits) at ERROR: "Error receiving from
client ...: WebSocket protocol error: Connection reset without closing handshake". That
is how clients usually leave, and nothing for the operator to do: it is logged at INFO
here. Any other error the SDK reports stays an ERROR.
"""

from __future__ import annotations

import logging

#: The SDK's logger for what it receives from each client (its Rust log, in Python's).
POLLER = "foxglove.websocket.connected_client.poller"
RESET = "Connection reset without closing handshake"


class ClientLeft(logging.Filter):
    """Turns the SDK's ERROR for a client gone without a closing handshake into INFO."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno >= logging.ERROR and RESET in record.getMessage():
            record.levelno, record.levelname = logging.INFO, logging.getLevelName(logging.INFO)
        return True


def quiet_client_resets() -> None:
    """Install the filter on the SDK's logger (once)."""
    logger = logging.getLogger(POLLER)
    if not any(isinstance(f, ClientLeft) for f in logger.filters):
        logger.addFilter(ClientLeft())
