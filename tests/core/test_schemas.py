"""The committed JSON Schemas match what the installed plugins generate."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest
import yaml

from hapticframe import get_registry
from hapticframe._cli import main
from hapticframe._schema import render_schemas, schema_diff, write_schemas

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))


def test_committed_schemas_are_fresh():
    problems = schema_diff(get_registry(), ROOT / "schemas")
    assert not problems, (
        "schemas/ is stale; regenerate with `hapticframe schema --write`:\n" + "\n".join(problems)
    )


def test_generation_is_deterministic_and_check_detects_staleness(tmp_path, capsys):
    first = render_schemas(get_registry())
    assert first == render_schemas(get_registry())
    write_schemas(get_registry(), tmp_path)
    assert main(["schema", "--check", "--dir", str(tmp_path)]) == 0
    victim = tmp_path / "experiment.schema.json"
    victim.write_text(victim.read_text().replace('"seed"', '"sead"', 1))
    (tmp_path / "plugins" / "sensor" / "gone.schema.json").write_text("{}")
    assert main(["schema", "--check", "--dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "stale" in err and "gone.schema.json" in err and "hapticframe schema --write" in err
    assert main(["schema", "--write", "--dir", str(tmp_path)]) == 0
    assert not (tmp_path / "plugins" / "sensor" / "gone.schema.json").exists()
    assert schema_diff(get_registry(), tmp_path) == []


@pytest.mark.parametrize("example", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_examples_point_editors_at_the_schema_and_satisfy_it(example):
    first = example.read_text().splitlines()[0]
    assert first == "# yaml-language-server: $schema=../schemas/experiment.schema.json"
    schema = json.loads((ROOT / "schemas" / "experiment.schema.json").read_text())
    jsonschema.validate(yaml.safe_load(example.read_text()), schema)


def test_the_schema_rejects_what_validation_rejects():
    schema = json.loads(render_schemas(get_registry())["experiment.schema.json"])
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"schema_version": 1, "name": "x", "seed": 1, "extra": 1}, schema)
