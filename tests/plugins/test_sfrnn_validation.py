"""What ``validate`` refuses of the contact-state classifiers and the sparse coder: raw
channels they cannot read, untrained weights streamed, mismatched sizes (issue 16)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, ValidationContext, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "perception-belief-map.yaml"
SFRNN = "classifiers[0]"


def _example() -> dict[str, Any]:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert data["classifiers"][0]["type"] == "sf-rnn" and data["run"]["train_from"]
    return data


def _issues(data: dict[str, Any]) -> dict[str, str]:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    return {issue.path: issue.message for issue in caught.value.issues}


def test_streaming_untrained_models_is_refused() -> None:
    data = _example()
    del data["run"]["train_from"]
    issues = _issues(data)
    assert "untrained weights" in issues[f"{SFRNN}.config.model_dir"]
    assert "no dictionaries" in issues["feature_extractors[1].config.dictionary_file"]


def test_hapticframe_train_may_fit_them() -> None:
    from hapticframe import Finding
    from hapticframe_sfrnn._checks import check
    from hapticframe_sfrnn._config import SFRNNConfig

    context = ValidationContext("sf-rnn", {}, {}, None, None, extra={"command": "train"})
    found = list(check(SFRNNConfig(), context))
    assert [f for f in found if isinstance(f, Finding)] == []  # only its declared sizes
    bare = ValidationContext("sf-rnn", {}, {}, None, None)
    assert [f.field for f in check(SFRNNConfig(), bare) if isinstance(f, Finding)] == [
        "model_dir"]


def test_an_sf_rnn_on_raw_biotac_channels_is_refused() -> None:
    data = _example()
    data["classifiers"][0]["inputs"] = ["fingertip"]
    message = _issues(data)[SFRNN]
    assert "all-zero input" in message and "fingertip (biotac)" in message


def test_a_linear_svm_reading_channels_no_input_gives_is_refused() -> None:
    data = _example()
    data["classifiers"][0] = {"id": "sf-rnn", "type": "linear-svm", "inputs": ["emd"]}
    assert "all-zero input" in _issues(data)[f"{SFRNN}.config.inputs"]
    data["classifiers"][0]["config"] = {"inputs": {"pdc_imfs": 25}}
    assert validate_mapping(data)


def test_sizes_and_amplitudes_must_match_the_coder() -> None:
    data = _example()
    data["classifiers"][0]["config"] = {"pdc_code_size": 50, "amplitude_inputs": True}
    assert "100 atoms" in _issues(data)[f"{SFRNN}.config.pdc_code_size"]
    data["classifiers"][0]["config"] = {"amplitude_inputs": True}
    data["feature_extractors"][1]["config"] = {"amplitude": "drop"}
    assert "amplitude: channel" in _issues(data)[f"{SFRNN}.config.amplitude_inputs"]


@pytest.mark.parametrize(("field", "value"), [("gru_units", 200_000), ("learning_rate", 1e300),
                                              ("frame_rate_hz", float("inf"))])
def test_unbounded_fields_are_refused(field: str, value: float) -> None:
    data = _example()
    data["classifiers"][0]["config"] = {field: value}
    assert f"{SFRNN}.config.{field}" in _issues(data)
