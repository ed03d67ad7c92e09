"""The committed JSON Schemas match what the installed plugins generate."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml

from hapticframe import get_registry
from hapticframe._kind import Kind
from hapticframe._manager import get_plugin_manager
from hapticframe._schema import render_schemas, schema_diff, shipped, write_schemas
from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.yaml"))
SUPPORT = ROOT / "tests" / "support"


def test_committed_schemas_are_fresh():
    problems = schema_diff(shipped(get_registry()), ROOT / "schemas")
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


@pytest.fixture
def lab_distribution_installed(tmp_path, monkeypatch):
    """A lab's plugin package installed beside hapticframe: a distribution on sys.path whose
    entry point registers the lab-local test plugin, seen by a fresh process-wide manager."""
    site = tmp_path / "site-packages"
    site.mkdir()
    shutil.copy(SUPPORT / "labplugin.py", site / "hf_schema_lab_plugin.py")
    info = site / "hf_schema_lab-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hf-schema-lab\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[hapticframe]\nlab = hf_schema_lab_plugin\n")
    monkeypatch.syspath_prepend(str(site))
    get_plugin_manager.cache_clear()
    yield
    get_plugin_manager.cache_clear()  # rebuilt without the lab once sys.path is restored
    sys.modules.pop("hf_schema_lab_plugin", None)


def test_a_lab_plugin_installed_beside_leaves_the_shipped_schemas_fresh(
    lab_distribution_installed, tmp_path, monkeypatch, capsys
):
    registry = get_registry()
    assert registry.plugins[Kind.SENSOR]["lab-sweep"].source.distribution == "hf-schema-lab"
    assert "lab-sweep" not in shipped(registry).plugins[Kind.SENSOR]
    monkeypatch.chdir(ROOT)
    assert main(["schema", "--check"]) == 0, capsys.readouterr().err
    # A lab writes schemas for everything installed, its own plugins included, elsewhere.
    lab_schemas = tmp_path / "lab-schemas"
    assert main(["schema", "--write", "--dir", str(lab_schemas)]) == 0
    assert (lab_schemas / "plugins" / "sensor" / "lab-sweep.schema.json").is_file()
    assert (lab_schemas / "plugins" / "map" / "bayesian-hilbert-map.schema.json").is_file()
    experiment = json.loads((lab_schemas / "experiment.schema.json").read_text())
    assert "lab-sweep" in json.dumps(experiment)
    assert main(["schema", "--check", "--dir", str(lab_schemas)]) == 0
    # The repository's schemas/ does not describe the lab's plugins: checked as a lab's
    # directory, it is missing them.
    assert main(["schema", "--check", "--dir", str(ROOT / "schemas")]) == 1
    assert "lab-sweep.schema.json" in capsys.readouterr().err
