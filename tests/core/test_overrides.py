"""``--set PATH=VALUE``: parsed, resolved, validated like the file, recorded (issue 18 §2)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from hapticframe import BenchOptions, ExperimentError, UsageError
from hapticframe._config import load_file
from hapticframe._config._overrides import (
    apply_overrides,
    parse_override,
    parse_value_list,
    validate_with_overrides,
)
from hapticframe.cli._cli import main

TINY = """\
schema_version: 1
name: tiny
seed: 3
scene:
  region: {x_min_m: 0.0, x_max_m: 0.3, y_min_m: 0.0, y_max_m: 0.2}
  objects:
    - {shape: circle, center_m: [0.15, 0.1], radius_m: 0.04}
robots:
  - id: arm
    type: sandbox
sensors:
  - id: wrist
    type: sandbox-force
    inputs: [arm]
classifiers:
  - id: jamming
    type: force-rate-jamming
    inputs: [wrist]
sensor_models:
  - id: failure-zone
    type: failure-zone-kernel
    inputs: [jamming, arm]
maps:
  - id: bhm
    type: bayesian-hilbert-map
    config:
      hinge_spacing_m: 0.05
    inputs: [failure-zone]
planners:
  - id: planner
    type: two-phase-coverage
    inputs: [bhm]
run:
  max_movements: 2
  figures: false
  record: false
"""
#: Line of ``hinge_spacing_m`` in :data:`TINY`.
HINGE_LINE = 27


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY, encoding="utf-8")
    return path


@pytest.mark.parametrize(("text", "path", "value"), [
    ("bhm.hinge_spacing_m=0.025", "bhm.hinge_spacing_m", 0.025),
    ("run.max_movements=10", "run.max_movements", 10),
    ("run.figures=true", "run.figures", True),
    ("run.force_limit_n=null", "run.force_limit_n", None),
    ("maps[0].config.kernel=[1, 2]", "maps[0].config.kernel", [1, 2]),
    ("scene.region={x_min_m: 0, x_max_m: 1}", "scene.region", {"x_min_m": 0, "x_max_m": 1}),
    ("name=a=b", "name", "a=b"),
])
def test_values_are_read_as_yaml(text: str, path: str, value: Any) -> None:
    override = parse_override(text)
    assert (override.path, override.value, override.text) == (path, value, text)


@pytest.mark.parametrize(("text", "says"), [
    ("bhm.hinge_spacing_m", "write PATH=VALUE"),
    ("=3", "write PATH=VALUE"),
    ("bhm.x=", "no value"),
    ("bhm..x=1", "not a dotted path"),
    ("bhm.x=[1, 2", "not YAML"),
    ("bhm.x=!!python/object:os.system ls", "not allowed"),
])
def test_malformed_overrides_are_usage_errors(text: str, says: str) -> None:
    with pytest.raises(UsageError, match=says) as caught:
        parse_override(text)
    assert "--set" in str(caught.value)


def test_value_lists_keep_lists_and_quoted_commas() -> None:
    assert parse_value_list("0.1,0.2, 3", "--vary") == [0.1, 0.2, 3]
    assert parse_value_list("[1, 2],[3]", "--vary") == [[1, 2], [3]]
    assert parse_value_list("'a,b',c", "--vary") == ["a,b", "c"]
    with pytest.raises(UsageError, match="no values"):
        parse_value_list(" ", "--vary")


def test_paths_resolve_by_list_index_by_component_id_and_at_the_top(tiny: Path) -> None:
    loaded = load_file(tiny)
    changed, applied = apply_overrides(loaded, [
        "bhm.hinge_spacing_m=0.1", "failure-zone.observation_spacing_m=0.02",
        "planners[0].config.line_spacing_m=0.04", "run.max_movements=5", "seed=9",
    ])
    assert [a.path for a in applied] == [
        "maps[0].config.hinge_spacing_m", "sensor_models[0].config.observation_spacing_m",
        "planners[0].config.line_spacing_m", "run.max_movements", "seed"]
    assert changed.data["maps"][0]["config"]["hinge_spacing_m"] == 0.1
    # A component without a config section gets one.
    assert changed.data["sensor_models"][0]["config"] == {"observation_spacing_m": 0.02}
    assert (applied[0].previous, applied[0].had_value) == (0.05, True)
    assert applied[1].had_value is False
    assert loaded.data["maps"][0]["config"]["hinge_spacing_m"] == 0.05  # the file is untouched
    assert changed.lines == loaded.lines


def test_a_mapping_built_in_code_is_copied_not_changed(tiny: Path) -> None:
    data = load_file(tiny).data
    changed, applied = apply_overrides(data, ["seed=4"])
    assert changed["seed"] == 4 and data["seed"] == 3 and applied[0].path == "seed"


@pytest.mark.parametrize(("text", "says"), [
    ("bmh.hinge_spacing_m=1", "neither a component id"),
    ("maps[3].config.x=1", "has 1 entries"),
    ("seed.x=1", "holds int, not a mapping"),
    ("bhm=1", "name a field"),
    ("run[0]=1", "not a list"),
])
def test_paths_that_name_nothing_are_usage_errors(tiny: Path, text: str, says: str) -> None:
    with pytest.raises(UsageError, match=says):
        apply_overrides(load_file(tiny), [text])


def test_an_id_that_is_also_a_top_level_key_is_ambiguous(tiny: Path) -> None:
    loaded = load_file(tiny)
    loaded.data["maps"][0]["id"] = "run"
    with pytest.raises(UsageError, match=r"both a component id .* maps\[0\]\.config\.x"):
        apply_overrides(loaded, ["run.x=1"])


def test_a_bad_value_is_located_as_in_the_file_with_a_note(tiny: Path) -> None:
    with pytest.raises(ExperimentError) as caught:
        validate_with_overrides(load_file(tiny), ["bhm.hinge_spacing_m=-1",
                                                  "planner.line_spacing=0.1"])
    rendered = caught.value.render()
    assert (f"tiny.yaml:{HINGE_LINE}: maps[0].config.hinge_spacing_m: " in rendered)
    assert "(the value came from --set bhm.hinge_spacing_m=-1)" in rendered
    # An unknown key: the file's own suggestion, at its nearest parent's line.
    assert "unknown key 'line_spacing'; did you mean 'line_spacing_m'" in rendered
    assert "(the value came from --set planner.line_spacing=0.1)" in rendered


def test_an_error_the_overrides_did_not_cause_has_no_note(tiny: Path) -> None:
    loaded = load_file(tiny)
    loaded.data["run"]["max_movements"] = 0
    with pytest.raises(ExperimentError) as caught:
        validate_with_overrides(loaded, ["seed=4"])
    assert "--set" not in caught.value.render()


def test_the_experiment_records_what_was_set(tiny: Path) -> None:
    experiment = validate_with_overrides(load_file(tiny), ["bhm.hinge_spacing_m=0.08",
                                                           "seed=11"])
    assert experiment.seed == 11
    bhm = next(c for c in experiment.components if c.id == "bhm")
    assert bhm.config.hinge_spacing_m == 0.08
    assert experiment.overrides[0] == {
        "set": "bhm.hinge_spacing_m=0.08", "path": "maps[0].config.hinge_spacing_m",
        "value": 0.08, "file_value": 0.05, "in_file": True}
    assert validate_with_overrides(load_file(tiny)).overrides == ()


def test_cli_run_records_overrides_in_run_json(tiny: Path, tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "out"
    assert main(["run", str(tiny), "--out", str(out), "--quiet",
                 "--set", "run.max_movements=1", "--set", "bhm.hinge_spacing_m=0.1"]) == 0
    record = json.loads((out / "run.json").read_text(encoding="utf-8"))
    assert [o["set"] for o in record["overrides"]] == ["run.max_movements=1",
                                                        "bhm.hinge_spacing_m=0.1"]
    assert record["resolved_config"]["run"]["max_movements"] == 1
    assert record["movements"] == 1


@pytest.mark.parametrize("command", ["validate", "run", "train"])
def test_cli_commands_refuse_a_bad_value_located(tiny: Path, tmp_path: Path, capsys: Any,
                                                 command: str) -> None:
    args = [command, str(tiny), "--set", "bhm.hinge_spacing_m=-1"]
    if command != "validate":
        args += ["--out", str(tmp_path / "out")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"tiny.yaml:{HINGE_LINE}: maps[0].config.hinge_spacing_m" in err
    assert "--set bhm.hinge_spacing_m=-1" in err
    assert not (tmp_path / "out").exists()


def test_cli_validate_says_ok_with_overrides_and_refuses_a_bad_path(tiny: Path,
                                                                    capsys: Any) -> None:
    assert main(["validate", str(tiny), "--set", "seed=5"]) == 0
    assert "ok" in capsys.readouterr().out
    assert main(["validate", str(tiny), "--set", "bmh.x=1"]) == 2
    assert "neither a component id" in capsys.readouterr().err
    with pytest.raises(SystemExit) as caught:
        main(["validate", str(tiny), "--set", "no-equals"])
    assert caught.value.code == 2


def test_bench_search_applies_overrides_to_every_trial(tmp_path: Path, monkeypatch: Any) -> None:
    from hapticframe_bench import _search

    seen: list[Any] = []

    def fake_run(experiment: Any, out_dir: Path, *, overwrite: bool, echo: Any) -> dict[str, Any]:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        seen.append(experiment)
        return {"object_found": True, "centroid_error_m": 0.01, "hausdorff_est_to_true_m": 0.01,
                "hausdorff_true_to_est_m": 0.01, "movements": 3, "ems_phase1": 2,
                "ems_phase2": 1, "object_interactions": 2, "max_force_n": 30.0,
                "wall_time_s": 0.1}

    monkeypatch.setattr(_search, "run_experiment", fake_run)
    options = BenchOptions(out_dir=tmp_path, trials=1, seed=1, workers=1, echo=lambda _l: None,
                           overrides=("bhm.hinge_spacing_m=0.07", "run.max_movements=3"))
    summary = _search.run_suite(options, shapes=("circle",))
    assert len(seen) == 3  # the two-phase planner, with Table 3.1 parameters, the baseline
    for experiment in seen:
        bhm = next(c for c in experiment.components if c.id == "bhm")
        assert bhm.config.hinge_spacing_m == 0.07
        assert experiment.model.run.max_movements == 3
        assert [o["set"] for o in experiment.overrides] == list(options.overrides)
    assert summary["overrides"] == list(options.overrides)
    assert "--set bhm.hinge_spacing_m=0.07" in summary["command"]


def test_bench_search_refuses_a_bad_override_before_any_run(tmp_path: Path,
                                                            monkeypatch: Any) -> None:
    from hapticframe_bench import _search

    def never(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("no trial may run")

    monkeypatch.setattr(_search, "run_experiment", never)
    options = BenchOptions(out_dir=tmp_path, trials=1, workers=1, echo=lambda _l: None,
                           overrides=("bhm.hinge_spacing_m=-1",))
    with pytest.raises(ExperimentError, match="came from --set"):
        _search.run_suite(options, shapes=("circle",))
