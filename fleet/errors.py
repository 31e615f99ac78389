"""The project's exception root: every error the fleet code raises on purpose is a
`FleetError`, so a caller can catch the project's refusals apart from its bugs.

`CodecError` is the family of bytes or values a codec refuses (a packet, a message, a
file); it is also a `ValueError`, so existing `except ValueError` handlers keep working.
Other errors keep their standard base beside `FleetError` for the same reason
(`class ScenarioError(FleetError, ValueError)`, `class RouterError(FleetError,
RuntimeError)`).

This module imports nothing, so every layer may use it.
"""

from __future__ import annotations

__all__ = ["CertError", "CodecError", "FleetError", "RosterError"]


class FleetError(Exception):
    """Root of every error the fleet code raises on purpose."""


class CodecError(FleetError, ValueError):
    """Bytes or values a codec cannot decode or encode; the message says what and where."""


class CertError(FleetError, RuntimeError):
    """The identities could not be written or read; the message names the file."""


class RosterError(FleetError, RuntimeError):
    """The signing keys or the roster could not be written or read; names the file."""
