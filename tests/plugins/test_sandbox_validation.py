"""What ``validate`` refuses of the sandbox robot and its force sensor, located (issue 16)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse.yaml"


def _example() -> dict[str, Any]:
    return yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("control_rate_hz", math.inf),
        ("control_rate_hz", 1e9),
        ("drag_coefficient_n_per_m2", math.inf),
        ("depth_m", math.inf),
        ("depth_m", math.nan),
        ("sector_radial_samples", 10_000_000),
        ("jamming_gain_n_per_m", 1e308),
    ],
)
def test_unbounded_robot_fields_are_refused(field: str, value: float) -> None:
    data = _example()
    data["robots"][0]["config"] = {field: value}
    assert f"robots[0].config.{field}" in _issues(data)


def test_infinite_sensor_noise_is_refused() -> None:
    data = _example()
    data["sensors"][0]["config"] = {"noise_std_n": math.inf}
    assert "sensors[0].config.noise_std_n" in _issues(data)


def test_a_depth_whose_free_drag_trips_the_force_limit_is_refused() -> None:
    data = _example()
    data["robots"][0]["config"] = {"depth_m": 0.2}  # c d² = 310 N > 80 N
    message = _issues(data)["robots[0].config.depth_m"]
    assert "310 N" in message and "force_limit_n" in message
    data["robots"][0]["config"] = {"depth_m": 0.06}  # 28 N: legal
    assert validate_mapping(data).components[0].id == "arm"


def test_following_a_robot_that_is_not_an_input_is_refused() -> None:
    data = _example()
    data["robots"][0]["config"] = {"follows": "planner"}
    assert "not among the sandbox's inputs" in _issues(data)["robots[0].config.follows"]
