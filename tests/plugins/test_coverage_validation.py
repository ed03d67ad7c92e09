"""What ``validate`` refuses of the coverage planners: speeds per control step, regions,
sampling grids (issue 16), each located at the planner's field."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SPEED = "planners[0].config.speed_m_per_s"


def _example(name: str = "search-ellipse.yaml") -> dict[str, Any]:
    return yaml.safe_load((EXAMPLES / name).read_text(encoding="utf-8"))


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


@pytest.mark.parametrize("speed", [1e-9, 1000.0])
def test_speeds_out_of_bounds_are_refused(speed: float) -> None:
    data = _example()
    data["planners"][0]["config"] = {"speed_m_per_s": speed}
    assert SPEED in _issues(data)


def test_a_line_that_cannot_end_within_the_step_limit_is_refused() -> None:
    data = _example()
    data["robots"][0]["config"] = {"control_rate_hz": 10_000}
    data["planners"][0]["config"] = {"speed_m_per_s": 1e-4}
    # The core refuses it first (the planner's own check stands behind it for runs the
    # core cannot judge), at the step limit, with the estimate.
    message = _issues(data)["run.max_steps_per_movement"]
    assert "9.014e+07 steps" in message and "max_steps_per_movement (100000)" in message


def test_a_step_over_the_smallest_object_is_refused() -> None:
    data = _example()  # the ellipse is 50 mm across its minor axis
    data["robots"][0]["config"] = {"control_rate_hz": 20}
    data["planners"][0]["config"] = {"speed_m_per_s": 1.2}  # 60 mm per step
    assert "jump over it" in _issues(data)[SPEED]  # the core's check, first


def test_a_step_over_the_failure_zone_is_refused() -> None:
    data = _example()
    data["scene"]["objects"] = [{"shape": "circle", "center_m": [0.4, 0.25], "radius_m": 0.1}]
    data["robots"][0]["config"] = {"control_rate_hz": 10, "min_depth_m": 0.04}
    data["planners"][0]["config"] = {"speed_m_per_s": 0.8}  # 80 mm; the zone is 65 mm
    assert "failure zone" in _issues(data)[SPEED]


def test_a_coarse_step_is_a_warning() -> None:
    data = _example()
    data["planners"][0]["config"] = {"speed_m_per_s": 0.6}  # 6 mm per 10 ms step
    # The core's check of a step against the smallest object (10 % of its width) says it.
    (warning,) = validate_mapping(data).warnings
    assert warning.path == SPEED and "few steps" in warning.message
    assert not validate_mapping(_example()).warnings


def test_a_region_smaller_than_one_line_is_refused() -> None:
    data = _example("search-circle-baseline.yaml")
    assert data["planners"][0]["type"] == "coverage"
    data["planners"][0]["config"] = {
        "region": {"x_min_m": 0.3, "x_max_m": 0.32, "y_min_m": 0.2, "y_max_m": 0.22}
    }
    assert "smaller than one coverage line" in _issues(data)["planners[0].config.line_spacing_m"]


@pytest.mark.parametrize(
    ("field", "value", "expected"),
    [
        ("grid_spacing_m", 1e-5, "map samples"),
        ("score_step_m", 1e-7, "points per candidate line"),
        ("map_id", "grid", "not one of the planner's inputs"),
    ],
)
def test_two_phase_sizes_and_map_are_checked(field: str, value: object, expected: str) -> None:
    data = _example()
    data["planners"][0]["config"] = {field: value}
    assert expected in _issues(data)[f"planners[0].config.{field}"]
