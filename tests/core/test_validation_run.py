"""Issue 16 §1: run settings and the closed loop's pace are checked at `validate`.

``run.evaluation_map``, ``run.label_channel`` and ``run.max_steps_per_movement`` against the
components; a planner's speed against the robots' control rates and the scene. Each
reproduction exits 2 at ``validate`` and ``run``, located, and writes nothing.
"""

from __future__ import annotations

import copy
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_file
from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]


def _ellipse() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    return data


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "mutant.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def refused(tmp_path: Path, data: dict[str, Any], capsys: pytest.CaptureFixture[str],
            *extra: str) -> str:
    path = _write(tmp_path, data)
    assert main(["validate", *extra, str(path)]) == 2
    text = capsys.readouterr().err
    out = tmp_path / "run"
    assert main(["run", *extra, str(path), "--out", str(out), "--quiet"]) == 2
    assert not out.exists()
    assert "internal error" not in text
    return text


def _component(data: dict[str, Any], section: str, cid: str) -> dict[str, Any]:
    entry: dict[str, Any] = next(e for e in data[section] if e["id"] == cid)
    return entry


def test_an_evaluation_map_that_is_no_component(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["run"]["evaluation_map"] = "nosuchmap"
    text = refused(tmp_path, data, capsys)
    assert "run.evaluation_map: run.evaluation_map 'nosuchmap' names no component" in text
    assert "'grid', 'bhm'" in text


def test_an_evaluation_map_that_is_a_planner(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["run"]["evaluation_map"] = "planner"
    assert "names a planner, not a map" in refused(tmp_path, data, capsys)


def test_one_step_per_movement_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["run"]["max_steps_per_movement"] = 1
    text = refused(tmp_path, data, capsys)
    # The diagonal of 0.75 x 0.5 m at 5 cm/s and 100 Hz: 1803 steps.
    assert "run.max_steps_per_movement:" in text and "1803 steps" in text


@pytest.mark.parametrize(("section", "cid", "field", "value"), [
    ("planners", "planner", "speed_m_per_s", 1e-4),  # slowest the field allows
    ("robots", "arm", "control_rate_hz", 1e4),  # fastest the field allows
])
def test_a_pace_that_cannot_end_a_movement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], section: str, cid: str, field: str,
    value: float,
) -> None:
    data = _ellipse()
    _component(data, section, cid).setdefault("config", {})[field] = value
    text = refused(tmp_path, data, capsys)
    # The core's check (run.max_steps_per_movement) or the planner's own validator may say
    # it first; either names the limit.
    assert "max_steps_per_movement" in text


def test_an_infinite_control_rate_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    _component(data, "robots", "arm")["config"] = {"control_rate_hz": float("inf")}
    assert "robots[0].config.control_rate_hz:" in refused(tmp_path, data, capsys)


def test_a_step_that_jumps_over_the_object(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    _component(data, "planners", "planner")["config"] = {"speed_m_per_s": 0.6}
    _component(data, "robots", "arm")["config"] = {"control_rate_hz": 10.0}  # 6 cm steps
    text = refused(tmp_path, data, capsys)
    assert "planners[0].config.speed_m_per_s:" in text


def test_a_coarse_step_is_a_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    _component(data, "planners", "planner")["config"] = {"speed_m_per_s": 0.6}  # 6 mm steps
    experiment = validate_file(_write(tmp_path, data))
    assert any(w.path == "planners[0].config.speed_m_per_s" and "few steps" in w.message
               for w in experiment.warnings)


def test_an_evaluation_grid_too_large_for_memory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["scene"]["region"] = {"x_min_m": 0.0, "x_max_m": 20.0, "y_min_m": 0.0,
                               "y_max_m": 20.0}
    text = refused(tmp_path, data, capsys)
    assert "run.evaluation_spacing_m:" in text and "6.4e+07 grid points" in text


@pytest.mark.parametrize("value", ["con tact", "a\x00b", ""])
def test_a_label_channel_that_is_no_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    data = _ellipse()
    data["run"]["label_channel"] = value
    assert "run.label_channel:" in refused(tmp_path, data, capsys)


LABELLED = textwrap.dedent('''
    from hapticframe import PluginConfig, SensorSpec, hookimpl

    class Config(PluginConfig):
        label_channel: str = "label"

        def declared_channels(self):
            return ("force_n", self.label_channel)

    @hookimpl
    def hapticframe_sensors():
        yield SensorSpec(name="labelled", summary="A finite sensor that says its channels.",
                         config=Config, factory="labelled_plugin:Sensor", inputs=(),
                         capabilities=frozenset({"finite"}))
''')


@pytest.fixture
def labelled(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    (tmp_path / "labelled_plugin.py").write_text(LABELLED, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "labelled_plugin"
    sys.modules.pop("labelled_plugin", None)


def _training(label_channel: str) -> dict[str, Any]:
    return {
        "schema_version": 1, "name": "labels", "seed": 1,
        "sensors": [{"id": "stream", "type": "labelled"},
                    {"id": "trials", "type": "labelled"}],
        "classifiers": [{"id": "jamming", "type": "force-rate-jamming", "inputs": ["stream"]}],
        "run": {"train_from": {"stream": "trials"}, "label_channel": label_channel},
    }


def test_a_label_channel_the_training_sensor_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], labelled: str
) -> None:
    text = refused(tmp_path, _training("contact"), capsys, "--plugin-module", labelled)
    assert "run.label_channel: training sensor 'trials' delivers no channel 'contact'" in text
    assert "(its channels: force_n, label)" in text


def test_a_label_channel_the_training_sensor_has(tmp_path: Path, labelled: str) -> None:
    experiment = validate_file(_write(tmp_path, _training("label")),
                               plugin_modules=[labelled])
    assert not experiment.warnings


def test_every_problem_is_reported_at_once(tmp_path: Path) -> None:
    data = copy.deepcopy(_ellipse())
    data["run"]["evaluation_map"] = "nosuchmap"
    data["run"]["max_steps_per_movement"] = 1
    data["scene"]["objects"][0]["center_m"] = [0.74, 0.21]
    with pytest.raises(ExperimentError) as caught:
        validate_file(_write(tmp_path, data))
    paths = {issue.path for issue in caught.value.issues}
    assert {"run.evaluation_map", "run.max_steps_per_movement",
            "scene.objects[0].center_m"} <= paths
    assert all(issue.line for issue in caught.value.issues)
