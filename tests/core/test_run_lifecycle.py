"""How a run begins and ends: components built and closed under one exit stack, failures
named and given the right exit status, interruptions recorded, provenance written."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from hapticframe.cli._cli import main

SUPPORT = Path(__file__).resolve().parent.parent / "support"
FAULTS = ("--plugin-module", "lab_faults")


def experiment(first: str = "none", second: str = "none", **second_config: object) -> str:
    extra = "".join(f", {k}: {v}" for k, v in second_config.items())
    return f"""\
schema_version: 1
name: lab-faults
seed: 1
sensors:
  - {{id: steady, type: lab-faulty, config: {{fault: {first}}}}}
  - {{id: faulty, type: lab-faulty, config: {{fault: {second}{extra}}}}}
"""


@pytest.fixture
def faults_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The fault plugin (registration and its sibling implementation) in a fresh working
    directory, imported afresh by each test."""
    for name in ("lab_faults.py", "lab_faults_impl.py"):
        shutil.copy(SUPPORT / name, tmp_path / name)
    for name in ("lab_faults", "lab_faults_impl"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run(directory: Path, text: str) -> tuple[int, Path]:
    path = directory / "faults.yaml"
    path.write_text(text)
    out = directory / "out"
    return main(["run", *FAULTS, str(path), "--out", str(out), "--quiet"]), out


def events() -> list[tuple[str, str]]:
    return list(sys.modules["lab_faults_impl"].EVENTS)


def test_a_factory_in_a_sibling_module_of_the_plugin_module_is_found(faults_dir):
    # lab_faults registers "lab_faults_impl:FaultySensor"; the directory is not on sys.path.
    assert str(faults_dir) not in sys.path
    code, out = run(faults_dir, experiment())
    assert code == 0 and json.loads((out / "run.json").read_text())["status"] == "ok"
    assert str(faults_dir) not in sys.path  # found without leaving the directory there
    assert events() == [("closed", "faulty"), ("closed", "steady")]  # reverse build order


def test_a_device_error_while_building_closes_what_was_built(faults_dir, capsys):
    code, out = run(faults_dir, experiment(second="build-oserror"))
    assert code == 1
    err = capsys.readouterr().err
    assert "cannot build 'faulty' (sensor 'lab-faulty'): OSError" in err and "busy" in err
    assert events() == [("closed", "steady")]
    assert not out.exists()  # an experiment that fails to build writes nothing


def test_a_type_error_inside_a_plugin_is_a_failure_not_an_invalid_experiment(faults_dir, capsys):
    code, _ = run(faults_dir, experiment(second="build-typeerror"))
    assert code == 1 and "cannot build 'faulty'" in capsys.readouterr().err
    code, out = run(faults_dir, experiment(second="read-typeerror"))
    assert code == 1
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed"
    assert record["error"].startswith("TypeError in 'faulty' (sensor)")
    assert ("closed", "faulty") in events() and ("closed", "steady") in events()


def test_a_close_that_raises_closes_the_others_and_still_writes_run_json(faults_dir, capsys):
    code, out = run(faults_dir, experiment(first="close"))
    assert code == 1
    assert events() == [("closed", "faulty"), ("closed", "steady")]
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed"
    assert "closing 'steady' failed: RuntimeError" in record["error"]
    assert "the port would not close" in capsys.readouterr().err


@pytest.mark.parametrize(("fault", "signal_name", "code"), [
    ("read-interrupt", "SIGINT", 130),
    ("read-sigterm", "SIGTERM", 143),
])
def test_an_interrupted_run_is_recorded_as_interrupted(faults_dir, capsys, fault, signal_name,
                                                       code):
    status, out = run(faults_dir, experiment(second=fault))
    assert status == code
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "interrupted" and record["signal"] == signal_name
    assert record["error"] is None
    assert ("closed", "faulty") in events() and ("closed", "steady") in events()
    assert f"interrupted ({signal_name})" in capsys.readouterr().err


def test_run_json_records_the_git_commit_and_the_scientific_dependencies(faults_dir):
    import numpy
    import pydantic

    from hapticframe.run._results import git_commit

    code, out = run(faults_dir, experiment())
    versions = json.loads((out / "run.json").read_text())["versions"]
    assert code == 0
    assert versions["numpy"] == numpy.__version__ and versions["pydantic"] == pydantic.VERSION
    assert "git_commit" in versions and versions["git_commit"] == git_commit()
    repository = Path(__file__).resolve().parents[2]
    if (repository / ".git").exists():
        assert len(versions["git_commit"].removesuffix("-dirty")) == 40


def test_git_commit_is_none_outside_a_checkout(monkeypatch, tmp_path):
    from hapticframe.run import _results
    _results.git_commit.cache_clear()
    monkeypatch.setattr(_results, "__file__", str(tmp_path / "hapticframe" / "_results.py"))
    try:
        assert _results.git_commit() is None
    finally:
        _results.git_commit.cache_clear()
