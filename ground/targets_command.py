"""`ground-cli targets make|show`: the thesis's Save Targets / Load Targets (3.1.3).

The file format and its validation are `fleet.mission.targets_file`'s; this module only turns
command-line text into targets and targets into text.
"""

from __future__ import annotations

import json

from fleet.errors import FleetError
from fleet.mission.messages import Target
from fleet.transport.targets_io import read_targets, write_targets


class TargetSyntaxError(FleetError, ValueError):
    """A LAT,LON,ALT argument that is not three numbers."""


def parse_target(text: str, index: int) -> Target:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 3:
        raise TargetSyntaxError(
            f"target {index} {text!r}: expected LAT,LON,ALT (degrees, degrees, metres)"
        )
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError as error:
        raise TargetSyntaxError(f"target {index} {text!r}: {error}") from error
    return Target(lat=lat, lon=lon, alt=alt)


def make(path: str, texts: list[str]) -> list[Target]:
    """Parse `texts` and write them to `path`; raises TargetSyntaxError or TargetsFileError."""
    targets = [parse_target(text, i) for i, text in enumerate(texts)]
    write_targets(path, targets)
    return targets


def show(path: str) -> list[Target]:
    """Read and validate `path`; raises TargetsFileError or OSError."""
    return read_targets(path)


def targets_json(targets: list[Target]) -> str:
    return json.dumps(
        [{"index": i, "lat": t.lat, "lon": t.lon, "alt": t.alt} for i, t in enumerate(targets)]
    )


def targets_table(targets: list[Target]) -> str:
    lines = [f"{'#':>3} {'LAT':>12} {'LON':>13} {'ALT m':>8}"]
    for i, t in enumerate(targets):
        lines.append(f"{i:>3} {t.lat:>12.6f} {t.lon:>13.6f} {t.alt:>8.1f}")
    return "\n".join(lines)
