"""Shared code: Piccolo link and planning-protocol codecs, geodesy, assignment, simulator."""

import os as _os

# Every program of the project imports this package first: a child started by a
# launcher (with $FLEET_PARENT_PID) is tied to it here, before its seconds of imports,
# so that it ends with the launcher even if the launcher dies while it starts.
if _os.environ.get("FLEET_PARENT_PID"):
    from fleet.lifeline import bind_from_env as _bind_from_env

    _bind_from_env()
