"""The docs quote code that exists: their Python snippets import what is there, and
docs/architecture.md names modules and folders that are.

A snippet is a fenced ```python block, or the code of a `python -c "..."` command in any
block. Every name it imports must be importable (a third-party package not installed
here is skipped, with the reason); a `python -c` command of the project's own modules
is run, in this process, and must finish.
"""

from __future__ import annotations

import ast
import contextlib
import importlib
import importlib.util
import io
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
#: The project's own top-level packages: a snippet's import of them must resolve.
PROJECT = {"fleet", "onboard", "ground", "tests", "bench"}

_FENCED = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)
_COMMAND = re.compile(r"""\bpython3? -c (["'])(.*?)\1""")


@dataclass(frozen=True)
class Snippet:
    where: str  #: file:line
    code: str
    command: bool  #: from a `python -c` command (run), else a fenced block (imports checked)


def _line(text: str, offset: int) -> int:
    return text.count("\n", 0, offset) + 1


def snippets() -> list[Snippet]:
    found = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        name = doc.relative_to(ROOT)
        for match in _FENCED.finditer(text):
            found.append(Snippet(f"{name}:{_line(text, match.start())}", match.group(1), False))
        for match in _COMMAND.finditer(text):
            found.append(Snippet(f"{name}:{_line(text, match.start())}", match.group(2), True))
    return found


def imports(code: str) -> list[tuple[str, tuple[str, ...]]]:
    """(module, names imported from it) for every import statement in `code`."""
    found: list[tuple[str, tuple[str, ...]]] = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            found.extend((alias.name, ()) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module is not None and not node.level:
            found.append((node.module, tuple(alias.name for alias in node.names)))
    return found


def _missing(module: str, names: tuple[str, ...]) -> list[str]:
    """What of `from module import names` (or `import module`) does not resolve."""
    try:
        loaded = importlib.import_module(module)
    except ImportError as error:
        return [f"{module} ({error})"]
    missing = []
    for name in names:
        if hasattr(loaded, name):
            continue
        try:
            importlib.import_module(f"{module}.{name}")
        except ImportError:
            missing.append(f"{module}.{name}")
    return missing


SNIPPETS = snippets()


def test_the_docs_have_snippets_to_check() -> None:
    # The patterns still find what the docs hold: a fenced block and a command at least.
    assert any(s.command for s in SNIPPETS) and any(not s.command for s in SNIPPETS)


@pytest.mark.parametrize("snippet", SNIPPETS, ids=[s.where for s in SNIPPETS])
def test_a_snippet_imports_what_exists(snippet: Snippet) -> None:
    found = imports(snippet.code)
    assert found, f"{snippet.where}: a snippet that imports nothing checks nothing"
    missing: list[str] = []
    for module, names in found:
        top = module.partition(".")[0]
        if top not in PROJECT and importlib.util.find_spec(top) is None:
            pytest.skip(f"{snippet.where}: {top} is not installed here")
        missing += _missing(module, names)
    assert not missing, f"{snippet.where} imports what does not exist: {', '.join(missing)}"


@pytest.mark.parametrize(
    "snippet",
    [s for s in SNIPPETS if s.command],
    ids=[s.where for s in SNIPPETS if s.command],
)
def test_a_python_command_of_the_projects_modules_runs(snippet: Snippet) -> None:
    tops = {module.partition(".")[0] for module, _ in imports(snippet.code)}
    if not tops <= PROJECT:
        pytest.skip(f"{snippet.where}: imports {', '.join(sorted(tops - PROJECT))}")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(snippet.code, snippet.where, "exec"), {"__name__": "__main__"})
    assert out.getvalue(), f"{snippet.where} printed nothing"


# ---- docs/architecture.md's modules ------------------------------------------------------------

ARCHITECTURE = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
#: A path in the tree: `fleet/transport/zenoh_bus.py`, `onboard/planner/`, ...
_PATH = re.compile(r"(?<![\w/.{])((?:fleet|onboard|ground|tests|bench)/(?:[\w.]+/)*[\w.]*)")
#: A dotted module (or a name in one): `fleet.launch.fork_client`, `onboard.main.fork_preload`.
_DOTTED = re.compile(r"(?<![\w/.-])((?:fleet|onboard|ground)(?:\.\w+)+)")


def named_paths() -> list[str]:
    paths = set()
    for match in _PATH.finditer(ARCHITECTURE):
        path = match.group(1)
        if path.endswith(".py") or path.endswith("/"):
            paths.add(path)
    return sorted(paths)


def named_modules() -> list[str]:
    return sorted(set(_DOTTED.findall(ARCHITECTURE)))


def test_architecture_names_modules_to_check() -> None:
    assert "onboard/core.py" in named_paths() and "fleet.transport.router" in named_modules()


@pytest.mark.parametrize("path", named_paths())
def test_a_path_in_the_architecture_exists(path: str) -> None:
    assert (ROOT / path).exists(), f"docs/architecture.md names {path}, which is not there"


@pytest.mark.parametrize("dotted", named_modules())
def test_a_module_in_the_architecture_exists(dotted: str) -> None:
    parts = dotted.split(".")
    # The longest importable prefix is the module; the rest are names in it.
    for cut in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            assert hasattr(found, name), f"docs/architecture.md names {dotted}: no {name}"
            found = getattr(found, name)
        return
    pytest.fail(f"docs/architecture.md names {dotted}, which does not import")
