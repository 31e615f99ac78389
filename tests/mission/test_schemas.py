import json
from pathlib import Path

import jsonschema
import msgspec
import pytest

from fleet.mission.messages import (
    MAX_TARGETS,
    AssignmentReport,
    MissionAbort,
    MissionTargets,
    UavResult,
)
from fleet.mission.schemas import MESSAGES, check_all, main, render
from tests.support.link_samples import sample_telemetry

#: The committed schemas, beside the tests in the repository.
SCHEMA_DIR = Path(__file__).resolve().parents[2] / "schemas"


@pytest.mark.parametrize("name", sorted(MESSAGES))
def test_committed_schema_matches_the_struct(name: str) -> None:
    path = SCHEMA_DIR / f"{name}.schema.json"
    assert path.exists(), f"{path} missing: run python -m fleet.mission.schemas"
    assert path.read_text() == render(name), f"{path} drifted: run python -m fleet.mission.schemas"


def test_no_stray_schema_files() -> None:
    names = {p.name.removesuffix(".schema.json") for p in Path(SCHEMA_DIR).glob("*.json")}
    assert names == set(MESSAGES)


def test_check_mode_passes_on_the_committed_schemas() -> None:
    assert check_all(SCHEMA_DIR) == []
    assert main(["--check", str(SCHEMA_DIR)]) == 0


def test_written_schemas_pass_the_check(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main([str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(f"{n}.schema.json" for n in MESSAGES)
    assert main(["--check", str(out)]) == 0


def test_check_mode_reports_missing_drifted_and_stray_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    main([str(tmp_path)])
    (tmp_path / "telemetry.schema.json").unlink()
    (tmp_path / "track.schema.json").write_text("{}\n")
    (tmp_path / "old.schema.json").write_text("{}\n")
    assert main(["--check", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "telemetry.schema.json: missing" in err
    assert "track.schema.json: drifted from Track" in err
    assert "old.schema.json: stray" in err
    assert not (tmp_path / "telemetry.schema.json").exists()


def test_default_directory_is_relative_to_the_current_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main([]) == 0
    assert (tmp_path / "schemas" / "telemetry.schema.json").is_file()


def test_help_prints_usage_and_writes_no_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit, match="0"):
        main(["--help"])
    assert "--check" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []


def test_unwritable_directory_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main([str(blocker / "schemas")]) == 2
    assert str(blocker / "schemas") in capsys.readouterr().err


def test_published_telemetry_validates_against_its_schema() -> None:
    schema = json.loads((SCHEMA_DIR / "telemetry.schema.json").read_text())
    jsonschema.validate(json.loads(msgspec.json.encode(sample_telemetry())), schema)


def test_out_of_range_ids_and_indices_are_refused_on_decode() -> None:
    """The bounds are in the schemas and enforced: never used as an index."""
    bad_index = (
        b'{"mission":1,"uav":74,"target":100,"pairs":{},"unassigned":[],"team":[],"digest":"x"}'
    )
    with pytest.raises(msgspec.ValidationError, match=r"Expected `int` <= 99 - at `\$.target`"):
        msgspec.json.decode(bad_index, type=AssignmentReport)
    with pytest.raises(msgspec.ValidationError, match=r"<= 4294967295 - at `\$.mission`"):
        msgspec.json.decode(b'{"mission": 4294967296}', type=MissionAbort)
    with pytest.raises(msgspec.ValidationError, match=r">= 1 - at `\$.uav`"):
        msgspec.json.decode(b'{"mission": 1, "uav": 0, "times": []}', type=UavResult)
    too_many = (
        b'{"mission": 1, "team": [74], "targets": ['
        + b",".join([b'{"lat": 1, "lon": 2, "alt": 3}'] * (MAX_TARGETS + 1))
        + b"]}"
    )
    with pytest.raises(msgspec.ValidationError, match=r"length <= 100 - at `\$.targets`"):
        msgspec.json.decode(too_many, type=MissionTargets)
    schema = json.loads((SCHEMA_DIR / "assignment_report.schema.json").read_text())
    report = schema["$defs"]["AssignmentReport"]["properties"]
    assert report["mission"]["maximum"] == 0xFFFF_FFFF
