"""JSON Schemas of every message on the fleet's Zenoh keys, generated from the structs.

`python -m fleet.mission.schemas [DIR]` writes one file per message type into `schemas/`;
a test regenerates them and fails when the committed files have drifted.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import msgspec

from fleet.mission.messages import (
    AssignmentReport,
    CommandResult,
    LinkHealth,
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    UavResult,
    UavState,
)
from fleet.piccolo.telemetry import Telemetry
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint

#: Schema file name -> (the struct, the key expressions that carry it).
MESSAGES: dict[str, tuple[type[msgspec.Struct], tuple[str, ...]]] = {
    "telemetry": (Telemetry, ("fleet/uav/{id}/telemetry",)),
    "track": (Track, ("fleet/uav/{id}/track", "fleet/uav/{id}/cmd/track (query payload)")),
    "waypoint": (
        Waypoint,
        ("fleet/uav/{id}/waypoint/{index}", "fleet/uav/{id}/cmd/waypoint (query payload)"),
    ),
    "status": (StatusText, ("fleet/uav/{id}/status",)),
    "link_health": (LinkHealth, ("fleet/uav/{id}/link",)),
    "uav_state": (UavState, ("fleet/uav/{id}/state (query reply)",)),
    "opm_command": (OpmCommand, ("fleet/uav/{id}/opm",)),
    "command_result": (CommandResult, ("fleet/uav/{id}/cmd/* (query reply)",)),
    "mission_targets": (MissionTargets, ("fleet/mission/{m}/targets",)),
    "uav_result": (UavResult, ("fleet/mission/{m}/result/{id}",)),
    "assignment_report": (AssignmentReport, ("fleet/mission/{m}/assignment/{id}",)),
    "mission_abort": (MissionAbort, ("fleet/mission/{m}/abort",)),
}

SCHEMA_DIR = Path(__file__).resolve().parents[2] / "schemas"


def render(name: str) -> str:
    struct, key_expressions = MESSAGES[name]
    schema = msgspec.json.schema(struct)
    schema["title"] = struct.__name__
    schema["x-key-expressions"] = list(key_expressions)
    return json.dumps(schema, indent=2, sort_keys=True) + "\n"


def write_all(directory: Path) -> list[Path]:
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name in MESSAGES:
        path = directory / f"{name}.schema.json"
        path.write_text(render(name))
        written.append(path)
    return written


def main() -> int:
    directory = Path(sys.argv[1]) if len(sys.argv) > 1 else SCHEMA_DIR
    for path in write_all(directory):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
