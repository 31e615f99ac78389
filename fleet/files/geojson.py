"""Loading a GeoJSON (or any JSON) file's document as hostile input."""

from __future__ import annotations

import json
from typing import Any

from fleet.errors import CodecError

__all__ = ["load_json"]


def load_json(data: bytes, source: str, error: type[CodecError]) -> Any:
    """The document in `data`; `error` naming `source` for anything that is not JSON."""
    try:
        return json.loads(data)
    except (UnicodeDecodeError, ValueError) as problem:
        raise error(f"{source}: not JSON ({problem})") from None
    except RecursionError:
        # Python's json parser recurses per level: a hostile file nested deeply enough
        # would otherwise end the command (or the page's request) with a traceback.
        raise error(f"{source}: nested too deeply to be GeoJSON") from None
