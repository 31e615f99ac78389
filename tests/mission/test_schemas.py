import json
from pathlib import Path

import msgspec
import pytest

from fleet.mission.schemas import MESSAGES, SCHEMA_DIR, render
from tests.link_samples import sample_telemetry


@pytest.mark.parametrize("name", sorted(MESSAGES))
def test_committed_schema_matches_the_struct(name: str) -> None:
    path = SCHEMA_DIR / f"{name}.schema.json"
    assert path.exists(), f"{path} missing: run python -m fleet.mission.schemas"
    assert path.read_text() == render(name), f"{path} drifted: run python -m fleet.mission.schemas"


def test_no_stray_schema_files() -> None:
    names = {p.name.removesuffix(".schema.json") for p in Path(SCHEMA_DIR).glob("*.json")}
    assert names == set(MESSAGES)


def test_published_telemetry_validates_against_its_schema() -> None:
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((SCHEMA_DIR / "telemetry.schema.json").read_text())
    jsonschema.validate(json.loads(msgspec.json.encode(sample_telemetry())), schema)
