"""What ``validate`` refuses of the BioTac feature extractors (issue 16), located."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "perception-belief-map.yaml"
CODES = "feature_extractors[1]"


def _example() -> dict[str, Any]:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert data["feature_extractors"][1]["type"] == "sparse-coding"
    return data


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


def test_a_coder_on_raw_biotac_channels_is_refused() -> None:
    data = _example()
    data["feature_extractors"][1]["inputs"] = ["fingertip"]
    assert "put emd-features between them" in _issues(data)[CODES]


def test_a_tensor_shape_the_features_do_not_have_is_refused() -> None:
    data = _example()
    data["feature_extractors"][1]["config"] = {"amplitude": "channel", "pac_shape": [8, 20]}
    assert "of shape (8, 22)" in _issues(data)[f"{CODES}.config.pac_shape"]
    data["feature_extractors"][0]["config"] = {"pac_samples_per_frame": 20}
    assert validate_mapping(data)


def test_a_dictionary_too_large_to_hold_is_refused_with_the_estimate() -> None:
    data = _example()
    data["feature_extractors"][1]["config"] = {"amplitude": "channel", "pac_atoms": 10_000,
                                               "pac_shape": [100, 200], "dictionary_file": "d"}
    assert "limit is 1e+08" in _issues(data)[f"{CODES}.config.pac_shape"]


def test_emd_features_on_a_force_sensor_are_refused() -> None:
    data = _example()
    data["sensors"].append({"id": "wrist", "type": "robotiq-ft300",
                            "config": {"port": "emulated"}})
    data["feature_extractors"][0]["inputs"] = ["wrist"]
    data.setdefault("run", {})["duration_s"] = 10.0  # the wrench sensor never ends
    assert "wire it to a BioTac" in _issues(data)["feature_extractors[0].config.modalities"]


@pytest.mark.parametrize(("field", "value"), [("pac_window_samples", 10**9),
                                              ("frame_rate_hz", float("inf"))])
def test_unbounded_fields_are_refused(field: str, value: float) -> None:
    data = _example()
    data["feature_extractors"][0]["config"] = {field: value}
    assert f"feature_extractors[0].config.{field}" in _issues(data)
