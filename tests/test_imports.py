"""The benchmarks and the tests do not import each other (lint-imports checks the
contracts); this checks the contract that keeps bench/ out of tests/ names everything."""

from __future__ import annotations

import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CONTRACT = "The benchmarks use the tests' shared support (tests.support), never a test module"


def test_bench_contract_forbids_every_test_package_and_module() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())
    contracts = {c["name"]: c for c in config["tool"]["importlinter"]["contracts"]}
    forbidden = set(contracts[CONTRACT]["forbidden_modules"])
    tests = REPO / "tests"
    present = {f"tests.{d.name}" for d in tests.iterdir() if (d / "__init__.py").exists()}
    present |= {f"tests.{f.stem}" for f in tests.glob("*.py") if f.name != "__init__.py"}
    assert present - {"tests.support"} == forbidden
