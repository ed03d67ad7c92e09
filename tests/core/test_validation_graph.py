"""Issue 16 §1: graph rules once checked only when building or running, now at `validate`.

A closed loop has exactly one planner and at least one robot; a component has the inputs
its kind needs; a plugin that needs a robot has one. Each exits 2 at ``validate`` and
``run``, located, and writes nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import validate_file
from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]


def _ellipse() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    return data


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "mutant.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def refused(tmp_path: Path, data: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> str:
    path = _write(tmp_path, data)
    assert main(["validate", str(path)]) == 2
    text = capsys.readouterr().err
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    assert not out.exists()
    assert "internal error" not in text
    return text


def test_two_planners(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    data["planners"].append({"id": "second", "type": "coverage", "inputs": ["bhm"]})
    text = refused(tmp_path, data, capsys)
    assert "planners[1]: a closed loop has exactly one planner; found 2" in text


def test_a_robot_without_a_planner(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    del data["planners"]
    assert "robots[0]: a closed loop needs a planner" in refused(tmp_path, data, capsys)


def test_a_planner_without_a_robot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    del data["robots"]
    data["sensors"][0]["inputs"] = []
    data["sensor_models"][0]["inputs"] = ["jamming"]
    text = refused(tmp_path, data, capsys)
    assert "planners[0]: a closed loop needs at least one robot" in text
    # The simulated force sensor is mounted on the robot: it says so too.
    assert "sensors[0].inputs: sensor 'wrist' (sandbox-force) needs a robot" in text


def test_a_classifier_with_no_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    data["classifiers"][0]["inputs"] = []
    text = refused(tmp_path, data, capsys)
    assert "classifiers[0].inputs: classifier 'jamming'" in text
    assert "name at least one in inputs" in text


def test_a_sensor_model_without_a_classifier(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["sensor_models"][0]["inputs"] = ["arm"]
    text = refused(tmp_path, data, capsys)
    assert "sensor_models[0].inputs:" in text and "exactly one classifier" in text


def test_a_sensor_model_with_two_classifiers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["classifiers"].append({"id": "second", "type": "force-rate-jamming",
                                "inputs": ["wrist"]})
    data["sensor_models"][0]["inputs"] = ["jamming", "second", "arm"]
    assert "(found 2)" in refused(tmp_path, data, capsys)


def test_a_simulated_sensor_without_its_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["sensors"][0]["inputs"] = []
    assert "sensors[0].inputs: sensor 'wrist' (sandbox-force) needs a robot" in refused(
        tmp_path, data, capsys)


def test_nothing_to_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = {"schema_version": 1, "name": "empty", "seed": 1,
            "maps": [{"id": "grid", "type": "occupancy-grid"}]}
    assert "nothing to run" in refused(tmp_path, data, capsys)


def test_a_map_nothing_updates_is_a_warning(tmp_path: Path) -> None:
    data = _ellipse()
    data["maps"].append({"id": "idle", "type": "occupancy-grid"})
    (warning,) = validate_file(_write(tmp_path, data)).warnings
    assert warning.path == "maps[2].inputs" and "never updated" in warning.message
    assert warning.line is not None


def test_a_map_planner_without_its_map_is_a_warning(tmp_path: Path) -> None:
    data = _ellipse()
    data["planners"][0]["inputs"] = []
    data["run"]["evaluation_map"] = "bhm"
    (warning,) = validate_file(_write(tmp_path, data)).warnings
    assert warning.path == "planners[0].inputs" and "plans on a map" in warning.message


def test_every_example_is_still_valid_without_warnings() -> None:
    for path in sorted((ROOT / "examples").glob("*.yaml")):
        assert validate_file(path).warnings == (), path.name
