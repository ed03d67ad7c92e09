"""The recurrent classifiers' code sizes follow the sparse coder's atoms when left None, so
that a sweep of ``codes.pac_atoms`` alone validates and builds (issue 18 §4)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping
from hapticframe._config._load import load_file
from hapticframe._config._overrides import Override, validate_with_overrides
from hapticframe.kinds import BuildContext

pytest.importorskip("torch")
pytest.importorskip("sklearn")

from hapticframe_sfrnn._config import SFRNNConfig
from hapticframe_sfrnn._recurrent import SFRNNClassifier
from hapticframe_tactile_features._config import SparseCodingConfig
from hapticframe_tactile_features._sparse_coding import SparseCodingExtractor

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "perception-belief-map.yaml"
ATOMS = {"pac_atoms": 12, "pdc_atoms": 8, "electrodes_atoms": 6, "fit_epochs": 1}
NET = {"fusion_units": 8, "gru_layers": 1, "gru_units": 4, "progress": False}


def _example() -> dict[str, Any]:
    return yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))


def _classifier(seed: int = 0, **config: Any) -> SFRNNClassifier:
    coder = SparseCodingExtractor(SparseCodingConfig(**ATOMS),
                                  BuildContext("codes", np.random.default_rng(seed)))
    return SFRNNClassifier(SFRNNConfig(**{**NET, **config}),
                           BuildContext("sf-rnn", np.random.default_rng(seed),
                                        inputs={"codes": coder}))


def test_unset_sizes_are_the_thesis_ones_until_an_input_says_otherwise() -> None:
    config = SFRNNConfig()
    assert config.pac_code_size is None
    assert [config.code_size(m) for m in ("pac", "pdc", "electrodes")] == [200, 100, 100]
    resolved = config.with_code_sizes({"pac": 50, "pdc": 25})
    assert (resolved.pac_code_size, resolved.pdc_code_size, resolved.code_size("electrodes")) \
        == (50, 25, 100)
    assert SFRNNConfig(pac_code_size=7).with_code_sizes({"pac": 50}).pac_code_size == 7


def test_a_sweep_of_the_atoms_alone_validates() -> None:
    loaded = load_file(EXAMPLE)
    for path, value in [("codes.pac_atoms", 50), ("codes.pdc_atoms", 200),
                        ("codes.electrodes_atoms", 25)]:
        experiment = validate_with_overrides(loaded, (Override(path, value, f"{path}={value}"),))
        codes = next(e for e in experiment.components if e.id == "codes")
        assert getattr(codes.config, path.split(".")[1]) == value


def test_a_size_set_in_the_file_must_still_match_the_atoms() -> None:
    data = _example()
    data["classifiers"][0]["config"]["pac_code_size"] = 200
    data["feature_extractors"][1]["config"]["pac_atoms"] = 50
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    issues = {i.path: i.message for i in caught.value.issues}
    message = issues["classifiers[0].config.pac_code_size"]
    assert "50 atoms" in message and "remove pac_code_size" in message


def test_the_network_is_built_for_the_coder_atoms_and_saved_so(tmp_path: Path) -> None:
    clf = _classifier()
    assert clf.groups == {"pac_code": 12, "pdc_code": 8, "electrodes_code": 6}
    assert (clf.config.pac_code_size, clf.config.electrodes_code_size) == (12, 6)
    clf.save(tmp_path / "model")
    loaded = SFRNNClassifier(SFRNNConfig(model_dir=str(tmp_path / "model"), progress=False),
                             BuildContext("sf-rnn", np.random.default_rng(1)))
    assert loaded.groups == clf.groups
    # A size given explicitly is what the network reads, whatever the input codes with.
    assert _classifier(pdc_code_size=8).groups["pdc_code"] == 8
