"""`ground-cli targets make|show`: the thesis's Save Targets / Load Targets (3.1.3).

The file format and its validation are `fleet.mission.targets_file`'s; this module only turns
command-line text into targets and targets into text.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from fleet.errors import FleetError
from fleet.files.targets_io import write_targets
from fleet.mission.messages import Target
from fleet.mission.targets_file import TargetsFileError
from fleet.transport.cli import ExitCode
from fleet.transport.command import LocalCommand, options_from
from ground import targets_formats
from ground.targets_formats import TargetsFormatError


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
    """Read and validate `path`, in the format its name implies (.csv, .geojson/.json,
    else the thesis's binary format: the files the page loads); raises
    TargetsFormatError or OSError."""
    return targets_formats.decode(Path(path).read_bytes(), path)


def targets_json(targets: list[Target]) -> str:
    return json.dumps(
        [{"index": i, "lat": t.lat, "lon": t.lon, "alt": t.alt} for i, t in enumerate(targets)]
    )


def targets_table(targets: list[Target]) -> str:
    lines = [f"{'#':>3} {'LAT':>12} {'LON':>13} {'ALT m':>8}"]
    for i, t in enumerate(targets):
        lines.append(f"{i:>3} {t.lat:>12.6f} {t.lon:>13.6f} {t.alt:>8.1f}")
    return "\n".join(lines)


@dataclass(frozen=True, kw_only=True)
class MakeOptions:
    out: str
    #: LAT,LON,ALT each.
    targets: tuple[str, ...]


def run_make(options: MakeOptions, out: TextIO) -> int:
    try:
        targets = make(options.out, list(options.targets))
    except (TargetSyntaxError, TargetsFileError) as error:
        print(f"error: {error}; {options.out} not written", file=sys.stderr)
        return ExitCode.FAILED
    except OSError as error:
        print(f"error: cannot write {options.out}: {error.strerror}", file=sys.stderr)
        return ExitCode.FAILED
    print(f"{options.out}: {len(targets)} targets written", file=out)
    return ExitCode.OK


def read_or_say(path: str, consequence: str = "") -> list[Target] | None:
    """`path`'s targets; or None, once stderr says why not (and `consequence`, if any)."""
    after = f"; {consequence}" if consequence else ""
    try:
        return show(path)
    except TargetsFormatError as error:
        print(f"error: {error}{after}", file=sys.stderr)
    except OSError as error:
        print(f"error: cannot read {path}: {error.strerror}{after}", file=sys.stderr)
    return None


@dataclass(frozen=True, kw_only=True)
class ShowOptions:
    file: str
    json: bool = False


def run_show(options: ShowOptions, out: TextIO) -> int:
    targets = read_or_say(options.file)
    if targets is None:
        return ExitCode.FAILED
    print(targets_json(targets) if options.json else targets_table(targets), file=out)
    return ExitCode.OK


def _make_options(args: argparse.Namespace) -> MakeOptions:
    return MakeOptions(out=args.out, targets=tuple(args.targets))


MAKE = LocalCommand(_make_options, run_make)
SHOW = LocalCommand(options_from(ShowOptions), run_show)
