"""Every code block of docs/plugin-authoring.md runs (issue 34 §4), so the guide cannot drift.

Each fenced block is taken from the page: ``file=`` blocks are written into their example's
package (the minimal sensor, ``example=minimal``, or the load cell), whose modules are then
imported; other Python blocks are executed; TOML is parsed and its entry point must name a
module of its package; YAML experiments are validated with the example's plugin loaded, and
fragments are checked component by component. The minimal sensor is also run through the
conformance kit and its experiment run. (tests/core/test_plugin_authoring.py builds the load
cell as a real distribution and runs its own tests.)
"""

from __future__ import annotations

import importlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from hapticframe import Kind, make_plugin_manager, validate_mapping
from hapticframe.cli._cli import main

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the backport, where installed
    tomllib = pytest.importorskip("tomli")

DOC = Path(__file__).resolve().parents[2] / "docs" / "plugin-authoring.md"
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```", re.S | re.M)
#: The languages the guide may use, and what is done with each.
LANGUAGES = {"python", "toml", "yaml", "text", "bash"}
MODULES = {"minimal": "hf_sine", "loadcell": "hf_loadcell"}


def _blocks() -> list[tuple[str, dict[str, str], str]]:
    found = []
    for lang, info, body in FENCE.findall(DOC.read_text(encoding="utf-8")):
        attrs = dict(part.split("=", 1) for part in info.split() if "=" in part)
        found.append((lang, attrs, body))
    return found


BLOCKS = _blocks()


def _example(attrs: dict[str, str]) -> str:
    return attrs.get("example", "loadcell")


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Both examples' files, written where their file= attributes say."""
    root = tmp_path_factory.mktemp("guide")
    roots = {name: root / name for name in MODULES}
    for _lang, attrs, body in BLOCKS:
        if "file" in attrs:
            path = roots[_example(attrs)] / attrs["file"]
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body, encoding="utf-8")
    return roots


@pytest.fixture
def on_path(written: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> dict[str, Path]:
    for package in written.values():
        monkeypatch.syspath_prepend(str(package / "src"))
    yield written
    for name in list(sys.modules):
        if name.split(".")[0] in MODULES.values():
            del sys.modules[name]


def test_the_guide_uses_only_languages_the_suite_runs():
    assert len(BLOCKS) >= 20, "the guide lost its blocks"
    assert {lang for lang, _, _ in BLOCKS} <= LANGUAGES
    assert BLOCKS[1][1] == {"example": "minimal", "file": "pyproject.toml"}  # the first example


def test_every_pyproject_is_valid_toml_naming_a_registration_module_it_ships(written):
    tomls = [(a, b) for lang, a, b in BLOCKS if lang == "toml"]
    assert {_example(a) for a, _ in tomls} == set(MODULES)
    for attrs, body in tomls:
        project = tomllib.loads(body)
        [(name, module)] = project["project"]["entry-points"]["hapticframe"].items()
        src = written[_example(attrs)] / "src" / (module.replace(".", "/") + ".py")
        assert src.is_file(), f"entry point {name} = {module!r} names no file of the guide"


def test_the_minimal_sensor_is_short_and_every_module_imports(on_path):
    sensor = on_path["minimal"] / "src" / "hf_sine" / "sensor.py"
    assert len(sensor.read_text().splitlines()) <= 45  # "about 40 lines"
    for attrs in (a for lang, a, _ in BLOCKS if lang == "python" and "file" in a):
        rel = Path(attrs["file"])
        if rel.parts[0] != "src":
            continue  # a test file: run below (minimal) or by test_plugin_authoring (load cell)
        module = ".".join(rel.with_suffix("").parts[1:]).removesuffix(".__init__")
        importlib.import_module(module)


@pytest.mark.parametrize(
    "index", [i for i, (lang, a, _) in enumerate(BLOCKS) if lang == "python" and "file" not in a]
)
def test_every_python_snippet_runs(index, on_path):
    _, _, body = BLOCKS[index]
    exec(compile(body, f"{DOC.name}[block {index}]", "exec"), {"__name__": "guide_snippet"})


def test_every_yaml_block_validates(on_path):
    yamls = [b for lang, _, b in BLOCKS if lang == "yaml"]
    assert len(yamls) >= 3
    registry = make_plugin_manager(modules=[f"{m}.plugin" for m in MODULES.values()]).registry
    for body in yamls:
        data = yaml.safe_load(body)
        if "schema_version" in data:
            validate_mapping(data, plugin_modules=[f"{m}.plugin" for m in MODULES.values()])
            continue
        for kind in Kind:
            for component in data.get(kind.section, []):
                spec = registry.get(kind, component["type"]).spec
                spec.config.model_validate(component.get("config", {}))


def test_the_minimal_sensor_passes_the_kit_and_its_experiment_runs(on_path, tmp_path):
    from hapticframe.testing import run_checks

    registry = make_plugin_manager(modules=["hf_sine.plugin"]).registry
    spec = registry.get(Kind.SENSOR, "lab-sine").spec
    # check_lazy_import asks a helper interpreter of its own, which does not see this test's
    # sys.path (test_plugin_authoring runs the whole kit on the installed load cell).
    results = run_checks(spec, registry=registry)
    assert "check_sensor_keeps_time" in {r.check for r in results}
    failed = [r for r in results if r.status != "PASS" and r.check != "check_lazy_import"]
    assert not failed, failed
    [body] = [b for lang, _, b in BLOCKS if lang == "yaml" and "lab-sine" in b]
    path = tmp_path / "sine.yaml"
    path.write_text(body)
    out = tmp_path / "out"
    assert main(["run", "--plugin-module", "hf_sine.plugin", str(path), "--out", str(out),
                 "--quiet"]) == 0
    times = np.load(out / "trace.npz")["sensor/wave/timestamps_s"]
    assert times.size == 100 and times[-1] == pytest.approx(2.0)  # 2 s at 50 Hz
    assert json.loads((out / "run.json").read_text())["status"] == "ok"


def test_a_blocked_plugin_is_named_as_blocked(tmp_path):
    registry = make_plugin_manager(blocked=["jamming"]).registry
    message = registry.unknown_message(Kind.CLASSIFIER, "force-rate-jamming")
    assert message.startswith("classifier type 'force-rate-jamming' is blocked")
    assert "'jamming' of hapticframe" in message and "unknown" not in message
    # An unrelated unknown type still says unknown, and that some entry points are blocked.
    other = registry.unknown_message(Kind.CLASSIFIER, "no-such-thing")
    assert other.startswith("unknown classifier type") and "'jamming'" in other
    path = tmp_path / "e.yaml"
    path.write_text(
        "schema_version: 1\nname: b\nseed: 1\nsensors:\n"
        "  - {id: rec, type: trace-recording, config: {path: t.npz}}\n"
        "classifiers:\n  - {id: j, type: force-rate-jamming, inputs: [rec]}\n"
    )
    env = {**os.environ, "HAPTICFRAME_BLOCKED_PLUGINS": "jamming"}
    proc = subprocess.run([sys.executable, "-m", "hapticframe", "validate", str(path)],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2
    err = proc.stderr
    assert "e.yaml:7: classifiers[0].type: classifier type 'force-rate-jamming' is blocked" in err
