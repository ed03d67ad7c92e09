"""What ``validate`` refuses of the failure-zone kernel: no robot or classifier to read, and
sector grids too fine to hold (issue 16), located."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse.yaml"


def _example() -> dict[str, Any]:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert data["sensor_models"][0]["inputs"] == ["jamming", "arm"]
    return data


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


def test_a_kernel_without_a_robot_is_refused() -> None:
    data = _example()
    data["sensor_models"][0]["inputs"] = ["jamming"]
    assert "add a robot to its inputs" in _issues(data)["sensor_models[0]"]


def test_a_kernel_without_a_classifier_is_refused() -> None:
    data = _example()
    data["sensor_models"][0]["inputs"] = ["arm"]
    # The core's graph check says it first (the plugin's validator stands behind it).
    assert "name one classifier" in _issues(data)["sensor_models[0].inputs"]


def test_a_sector_grid_too_fine_to_hold_is_refused_with_the_estimate() -> None:
    data = _example()
    data["sensor_models"][0]["config"] = {"sector_spacing_m": 1e-5}
    message = _issues(data)["sensor_models[0].config.sector_spacing_m"]
    assert "points per observation" in message and "limit is 2e+05" in message


@pytest.mark.parametrize("field", ["initial_depth_m", "max_range_m", "empirical_gamma_scale_cm2"])
def test_infinite_fields_are_refused(field: str) -> None:
    data = _example()
    data["sensor_models"][0]["config"] = {field: float("inf")}
    assert f"sensor_models[0].config.{field}" in _issues(data)
