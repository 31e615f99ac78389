"""JSON Schemas of every message on the fleet's Zenoh keys, generated from the structs.

Which struct travels on which key comes from the key registry
(`fleet.mission.key_registry`); each schema lists those keys in `x-key-expressions`.

`python -m fleet.mission.schemas [DIR]` writes one file per message type into DIR
(default: `schemas` in the current directory, the repository's `schemas/` when run from
its root); `--check` writes nothing and exits 1 if a file is missing, drifted or stray.
A test does the same check on the committed files.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import msgspec

from fleet.mission.key_registry import DEFAULT_PREFIX, REGISTRY, SCHEMA_FILES, Carriage, KeySpec


def _key_expressions(spec: KeySpec) -> dict[type[msgspec.Struct], str]:
    """What each struct of `spec` is shown as: its key, and where it travels otherwise."""
    key = f"{DEFAULT_PREFIX}/{spec.pattern}"
    shown: dict[type[msgspec.Struct], str] = {}
    if spec.message is not None:
        notes = [] if Carriage.PUT in spec.carriage else ["query payload"]
        notes += [spec.note] if spec.note else []
        shown[spec.message] = f"{key} ({'; '.join(notes)})" if notes else key
    if spec.reply is not None and spec.reply is not spec.message:
        shown[spec.reply] = f"{key} (query reply)"
    return shown


def _messages() -> dict[str, tuple[type[msgspec.Struct], tuple[str, ...]]]:
    found: dict[type[msgspec.Struct], list[str]] = {struct: [] for struct in SCHEMA_FILES}
    for spec in REGISTRY:
        for struct, shown in _key_expressions(spec).items():
            found[struct].append(shown)
    return {SCHEMA_FILES[struct]: (struct, tuple(shown)) for struct, shown in found.items()}


#: Schema file name -> (the struct, the key expressions that carry it), from the registry.
MESSAGES = _messages()

#: Where the schemas go by default, relative to the current directory.
DEFAULT_DIR = Path("schemas")
_SUFFIX = ".schema.json"


def render(name: str) -> str:
    struct, key_expressions = MESSAGES[name]
    schema = msgspec.json.schema(struct)
    schema["title"] = struct.__name__
    schema["x-key-expressions"] = list(key_expressions)
    return json.dumps(schema, indent=2, sort_keys=True) + "\n"


def write_all(directory: Path) -> list[Path]:
    """Write every schema into `directory` (created if needed); return the paths."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name in MESSAGES:
        path = directory / f"{name}{_SUFFIX}"
        path.write_text(render(name))
        written.append(path)
    return written


def check_all(directory: Path) -> list[str]:
    """What differs between `directory` and the structs: one line per file, [] if none."""
    problems = []
    for name in MESSAGES:
        path = directory / f"{name}{_SUFFIX}"
        if not path.is_file():
            problems.append(f"{path}: missing")
        elif path.read_text() != render(name):
            problems.append(f"{path}: drifted from {MESSAGES[name][0].__name__}")
    for path in sorted(directory.glob(f"*{_SUFFIX}")):
        if path.name.removesuffix(_SUFFIX) not in MESSAGES:
            problems.append(f"{path}: stray (no message of that name)")
    return problems


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m fleet.mission.schemas",
        description="Write (or check) the JSON Schema of every message on the Zenoh keys.",
    )
    parser.add_argument(
        "directory",
        nargs="?",
        type=Path,
        default=DEFAULT_DIR,
        help=f"output directory (default: {DEFAULT_DIR}/ in the current directory)",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 if a schema file is missing, drifted or stray",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Exit codes: 0 written or up to date, 1 --check found differences, 2 bad usage/I-O."""
    args = _parser().parse_args(argv)
    directory: Path = args.directory
    try:
        if args.check:
            problems = check_all(directory)
            for problem in problems:
                print(problem, file=sys.stderr)
            return 1 if problems else 0
        for path in write_all(directory):
            print(path)
    except OSError as error:
        print(f"schemas: {directory}: {error.strerror or error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
