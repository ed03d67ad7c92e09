"""What ``validate`` refuses of the force observer: inputs without the channels it reads."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "free-motion-ft300.yaml"


def _example() -> dict[str, Any]:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    (observer,) = [c for c in data["feature_extractors"] if c["type"] == "force-observer"]
    assert observer["inputs"] == ["wrist", "imu"]
    return data


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


def test_an_observer_without_a_force_sensor_is_refused() -> None:
    data = _example()
    data["feature_extractors"][0]["inputs"] = ["imu"]
    assert "'force_n'" in _issues(data)["feature_extractors[0].config.force_channel"]


def test_a_mass_without_an_imu_is_refused_and_a_pass_through_is_not() -> None:
    data = _example()
    data["feature_extractors"][0]["inputs"] = ["wrist"]
    data["feature_extractors"][0]["config"] = {"mass_kg": 0.8}
    assert "feature_extractors[0].config.acceleration_channel" in _issues(data)
    data["feature_extractors"][0]["config"] = {}
    assert validate_mapping(data)


def test_a_negative_or_huge_mass_is_refused() -> None:
    for mass in (-1.0, 1e12):
        data = _example()
        data["feature_extractors"][0]["config"] = {"mass_kg": mass}
        assert "feature_extractors[0].config.mass_kg" in _issues(data)
