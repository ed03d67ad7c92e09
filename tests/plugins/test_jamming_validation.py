"""What ``validate`` refuses of the jamming classifier: a sensor whose channels it cannot
read (issue 16), and unbounded thresholds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _example(name: str) -> dict[str, Any]:
    data = yaml.safe_load((EXAMPLES / name).read_text(encoding="utf-8"))
    assert data["classifiers"][0]["type"] == "force-rate-jamming"
    return data


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


def test_a_classifier_wired_to_an_imu_is_refused() -> None:
    data = _example("search-ellipse-ft300.yaml")
    data["classifiers"][0]["inputs"] = ["imu"]
    message = _issues(data)["classifiers[0].config.force_channel"]
    assert "'force_n'" in message and "imu (bno055)" in message


def test_a_force_channel_no_input_delivers_is_refused() -> None:
    data = _example("search-ellipse.yaml")
    data["classifiers"][0]["config"] = {"force_channel": "force"}
    assert "classifiers[0].config.force_channel" in _issues(data)


def test_a_recording_is_not_second_guessed() -> None:
    # A recording's channels are known only once it is read: not checked at validate.
    data = _example("calibrate-jamming.yaml")
    data["classifiers"][0]["config"] = {"force_channel": "anything"}
    assert [c.id for c in validate_mapping(data).components] == ["wrist", "jamming"]


@pytest.mark.parametrize(("field", "value"), [("cutoff_hz", float("inf")),
                                              ("jamming_force_n", 1e300),
                                              ("restart_after_gap_s", 1e9)])
def test_unbounded_fields_are_refused(field: str, value: float) -> None:
    data = _example("search-ellipse.yaml")
    data["classifiers"][0]["config"] = {field: value}
    assert f"classifiers[0].config.{field}" in _issues(data)
