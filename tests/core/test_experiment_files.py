"""Malformed experiment files: exit status 2, a located message, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hapticframe import ExperimentError
from hapticframe._config import load_text
from hapticframe.cli._cli import main
from tests.support.lab import lab_main, validate_lab

GOOD = (Path(__file__).parents[1] / "support" / "lab-open-loop.yaml").read_text()

BOMB = "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 9) if p else ', '.join(['x'] * 9)}]\n"
    for p, c in zip(["", "a", "b", "c", "d", "e", "f"], "abcdefg", strict=True)
)

CASES = {
    # name: (file name, content bytes, expected fragment, expected line)
    "syntax": ("e.yaml", b"name: [unclosed\n", "YAML syntax error", 2),
    "not-utf8": ("e.yaml", b"name: x\n\xff\xfe\n", "not UTF-8", 2),
    "empty": ("e.yaml", b"", "empty", None),
    "only-comments": ("e.yaml", b"# nothing\n\n", "empty", None),
    "wrong-top-type": ("e.yaml", b"- a\n- b\n", "top level must be a mapping", 1),
    "wrong-value-type": ("e.yaml", GOOD.replace("seed: 3", "seed: three").encode(), "seed", 4),
    "unknown-key": ("e.yaml", GOOD.replace("name: lab", "nmae: x\nname: lab").encode(),
                    "did you mean 'name'", 3),
    "unknown-config-key": ("e.yaml", GOOD.replace("samples: 300", "sampels: 300").encode(),
                           ("sensors[0].config.sampels: unknown key 'sampels'; "
                            "did you mean 'samples'"), 12),
    # Suggestions at every nesting level: run settings, the scene, its material and objects.
    "unknown-run-key": ("e.yaml", (GOOD + "run:\n  evalution_map: cells\n").encode(),
                        ("run.evalution_map: unknown key 'evalution_map'; did you mean "
                         "'evaluation_map'"), 24),
    "unknown-material-key": ("e.yaml", GOOD.replace(
        "scene:\n", "scene:\n  material: {friction_angel_deg: 40.0}\n").encode(),
        ("scene.material.friction_angel_deg: unknown key 'friction_angel_deg'; did you mean "
         "'friction_angle_deg'"), 7),
    "unknown-object-key": ("e.yaml",
                           GOOD.replace("radius_m: 0.03}", "radius_m: 0.03, raduis: 1}").encode(),
                           ("scene.objects[0].raduis: unknown key 'raduis'; "
                            "did you mean 'radius_m'"), 8),
    "unknown-plugin": ("e.yaml", GOOD.replace("type: lab-cells", "type: lab-celss").encode(),
                       "did you mean 'lab-cells'", 21),
    "duplicate-id": ("e.yaml", GOOD.replace("id: cells", "id: point").encode(),
                     "duplicate id 'point'", 20),
    "dangling-input": ("e.yaml", GOOD.replace("inputs: [point]", "inputs: [pont]").encode(),
                       "input 'pont' is not the id of any component; did you mean 'point'", 22),
    "wrong-input-kind": ("e.yaml", GOOD.replace("inputs: [point]", "inputs: [sweep]").encode(),
                         "cannot read 'sweep', a sensor", 22),
    "self-input": ("e.yaml", GOOD.replace("inputs: [sweep]", "inputs: [sweep, contact]").encode(),
                   "cannot be its own input", 16),
    "alias-bomb": ("e.yaml", BOMB.encode(), "alias bomb", None),
    "python-tag": ("e.yaml",
                   b"schema_version: 1\nname: !!python/object/apply:os.system [ls]\nseed: 1\n",
                   "is not allowed", 2),
    "duplicate-key": ("e.yaml", b"schema_version: 1\nname: a\nname: b\nseed: 1\n",
                      "duplicate key 'name'", 3),
    "bad-version": ("e.yaml", GOOD.replace("schema_version: 1", "schema_version: 7").encode(),
                    "schema_version must be 1", 2),
    "json-syntax": ("e.json", b'{"name": 1,,}', "JSON syntax error", 1),
    "toml-syntax": ("e.toml", b"name = [", "TOML syntax error", None),
    "unknown-suffix": ("e.ini", b"name=1", "unknown file type", None),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_malformed_files_exit_2_located_and_write_nothing(case, lab_dir, capsys):
    name, content, fragment, line = CASES[case]
    path = lab_dir / name
    path.write_bytes(content)
    out = lab_dir / "out"
    assert lab_main(["validate", str(path)]) == 2
    assert lab_main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert fragment in err, err
    assert "Traceback" not in err
    if line is not None:
        assert f"{path}:{line}:" in err, err
    assert not out.exists()


def test_a_cycle_is_reported(lab_dir, capsys):
    text = GOOD.replace("classifiers:", """feature_extractors:
  - {id: fe1, type: lab-scale, inputs: [sweep, fe2]}
  - {id: fe2, type: lab-scale, inputs: [fe1]}
classifiers:""")
    path = lab_dir / "cyc.yaml"
    path.write_text(text)
    assert lab_main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "inputs form a cycle: fe1 -> fe2 -> fe1" in err
    assert f"{path}:14:" in err


def test_every_problem_is_reported_at_once(lab_dir):
    bad = GOOD.replace("samples: 300", "samples: -1").replace("chunk: 20", "chunk: x")
    path = lab_dir / "two.yaml"
    path.write_text(bad)
    with pytest.raises(ExperimentError) as info:
        validate_lab(path)
    paths = {issue.path for issue in info.value.issues}
    assert {"sensors[0].config.samples", "sensors[0].config.chunk"} <= paths


def test_json_and_toml_files_validate(lab_dir):
    data = {
        "schema_version": 1, "name": "j", "seed": 1,
        "sensors": [{"id": "s", "type": "lab-sweep"}],
    }
    (lab_dir / "e.json").write_text(json.dumps(data, indent=1))
    assert validate_lab(lab_dir / "e.json").components[0].id == "s"
    (lab_dir / "e.toml").write_text(
        'schema_version = 1\nname = "t"\nseed = 1\n'
        '[[sensors]]\nid = "s"\ntype = "lab-sweep"\nconfig = {samples = 5}\n'
    )
    assert validate_lab(lab_dir / "e.toml").components[0].config.samples == 5


def test_json_errors_carry_lines(lab_dir):
    (lab_dir / "e.json").write_text('{\n "schema_version": 1,\n "name": "j",\n "seed": "x"\n}\n')
    with pytest.raises(ExperimentError) as info:
        validate_lab(lab_dir / "e.json")
    assert info.value.issues[0].line == 4


def test_yaml_loader_keeps_plain_data_only():
    loaded = load_text("a: 2020-01-01\nb: [1, 2.5, true, null]\n", "x.yaml", ".yaml")
    assert loaded.data == {"a": "2020-01-01", "b": [1, 2.5, True, None]}
    assert loaded.line_of("b[1]") == 2


def test_a_file_that_names_code_to_import_is_rejected_before_importing_it(lab_dir, capsys):
    (lab_dir / "payload.py").write_text("import pathlib\npathlib.Path('ran').write_text('x')\n")
    path = lab_dir / "m.yaml"
    marker = "# (its plugins come"
    path.write_text(GOOD.replace(marker, f"plugin_modules: [payload]\n{marker}"))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "plugin_modules" in err and "never name code to import" in err and ":5" in err
    assert not (lab_dir / "ran").exists()  # the module beside the file was never imported


def test_plugin_module_option_errors_exit_2(lab_dir, capsys):
    path = str(lab_dir / "lab-open-loop.yaml")
    assert main(["validate", "--plugin-module", "no_such_lab_module", path]) == 2
    assert "--plugin-module" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:  # a path is not a module name
        main(["validate", "--plugin-module", "../labplugin", path])
    assert info.value.code == 2
    # Without the option the lab's plugin types are unknown: a located error, exit 2.
    assert main(["validate", path]) == 2
    assert "lab-sweep" in capsys.readouterr().err
    assert lab_main(["validate", path]) == 0
