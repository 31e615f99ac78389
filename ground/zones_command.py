"""Reading `send-targets --no-fly ZONES.geojson`: the zones, checked against the targets.

Both are checked before anything touches the network: a zones file that is not usable,
or a target inside a zone, sends nothing, whatever `--force` says (no route could reach
such a target, and every UAV would refuse the mission).
"""

from __future__ import annotations

import sys

from fleet.files.zones_file import ZonesFileError, read_zones
from fleet.mission.messages import NoFlyZone, Target
from fleet.mission.no_fly import mission_zone_problem


def zones_or_say(path: str | None, targets: tuple[Target, ...]) -> tuple[NoFlyZone, ...] | None:
    """The zones in `path` (none without one); None, once stderr says why not."""
    if path is None:
        return ()
    try:
        zones = read_zones(path)
    except ZonesFileError as error:
        print(f"error: {error}; nothing sent", file=sys.stderr)
        return None
    except OSError as error:
        print(f"error: cannot read {path}: {error.strerror}; nothing sent", file=sys.stderr)
        return None
    problem = mission_zone_problem(zones, targets)
    if problem is not None:
        print(f"error: {path}: {problem}; nothing sent", file=sys.stderr)
        return None
    return zones
