"""Corrupt saved models of sf-rnn, fusion-rnn and linear-svm: each is a ValueError naming the
file, raised before any network is built (issue 16 §2, model artifacts)."""

from __future__ import annotations

import json
import os
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from hapticframe.kinds import BuildContext
from hapticframe_sfrnn import (
    FusionRNNClassifier,
    FusionRNNConfig,
    LinearSVMClassifier,
    LinearSVMConfig,
    SFRNNClassifier,
    SFRNNConfig,
)

SMALL = {"pac_code_size": 6, "pdc_code_size": 5, "electrodes_code_size": 4, "progress": False}
ARCHITECTURES: dict[str, tuple[Any, Any, dict[str, Any]]] = {
    "sf-rnn": (SFRNNClassifier, SFRNNConfig,
               {**SMALL, "fusion_units": 8, "gru_layers": 2, "gru_units": 8}),
    "fusion-rnn": (FusionRNNClassifier, FusionRNNConfig,
                   {**SMALL, "branch_layers": 1, "branch_units": 4, "fusion_units": 8}),
}
# The field each architecture's width lives in (what a mis-sized model.json edits).
WIDTH = {"sf-rnn": "gru_units", "fusion-rnn": "branch_units"}
DEPTH = {"sf-rnn": "gru_layers", "fusion-rnn": "branch_layers"}


def build(arch: str, model_dir: Path | None = None) -> Any:
    cls, config_type, small = ARCHITECTURES[arch]
    config = config_type(model_dir=str(model_dir)) if model_dir else config_type(**small)
    return cls(config, BuildContext("rnn", np.random.default_rng(0)))


@pytest.fixture(params=sorted(ARCHITECTURES))
def saved(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[str, Path]:
    """An untrained small network saved by save() (train-free; its weights are seeded)."""
    build(request.param).save(tmp_path / "model")
    return request.param, tmp_path / "model"


def refused(arch: str, model_dir: Path, match: str) -> str:
    with pytest.raises(ValueError, match=match) as info:
        build(arch, model_dir)
    message = str(info.value)
    assert "weights_only=False" not in message and len(message) < 1000
    return message


def edit_meta(model_dir: Path, change: Callable[[dict[str, Any]], Any]) -> None:
    path = model_dir / "model.json"
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))


def edit_state(model_dir: Path, change: Callable[[dict[str, torch.Tensor]], Any]) -> None:
    state = torch.load(model_dir / "weights.pt", weights_only=True)
    change(state)
    torch.save(state, model_dir / "weights.pt")


def test_a_saved_model_loads_and_predicts_the_same(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    loaded = build(arch, model_dir)
    original = build(arch)
    for (name, a), b in zip(original.net.state_dict().items(), loaded.net.state_dict().values(),
                            strict=True):
        assert torch.equal(a, b), name


def test_truncated_weights(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    data = (model_dir / "weights.pt").read_bytes()
    (model_dir / "weights.pt").write_bytes(data[: len(data) // 2])
    assert "weights.pt" in refused(arch, model_dir, "truncated")


def test_empty_weights_and_empty_metadata(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    (model_dir / "weights.pt").write_bytes(b"")
    refused(arch, model_dir, r"weights\.pt is empty")
    (model_dir / "model.json").write_bytes(b"")
    refused(arch, model_dir, r"model\.json is empty")


def test_truncated_metadata(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    text = (model_dir / "model.json").read_text()
    (model_dir / "model.json").write_text(text[: len(text) // 2])
    refused(arch, model_dir, r"model\.json is not valid JSON .* truncated")


def test_metadata_that_describes_another_width_is_refused_by_the_weights_shape(
    saved: tuple[str, Path],
) -> None:
    arch, model_dir = saved
    edit_meta(model_dir, lambda m: m["config"].update({WIDTH[arch]: 51}))
    refused(arch, model_dir, r"weights\.pt: .* has shape .* model\.json describes")


def test_a_reshaped_tensor(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    edit_state(model_dir, lambda s: s.update({"readout.weight": s["readout.weight"].T.clone()}))
    refused(arch, model_dir, r"weights\.pt: readout\.weight has shape")


def test_missing_extra_and_retyped_tensors(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    state = torch.load(model_dir / "weights.pt", weights_only=True)
    torch.save({k: v for k, v in state.items() if k != "readout.bias"}, model_dir / "weights.pt")
    refused(arch, model_dir, r"lacks readout\.bias")
    torch.save({**state, "extra": torch.zeros(2)}, model_dir / "weights.pt")
    refused(arch, model_dir, "unexpected extra")
    torch.save({**state, "readout.bias": state["readout.bias"].double()}, model_dir / "weights.pt")
    refused(arch, model_dir, r"readout\.bias holds torch\.float64")
    torch.save([state["readout.bias"]], model_dir / "weights.pt")
    refused(arch, model_dir, "mapping of tensor names")


def test_nan_and_infinite_weights(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    edit_state(model_dir, lambda s: s["readout.weight"].view(-1)[0].fill_(float("nan")))
    refused(arch, model_dir, r"readout\.weight holds 1 NaN or infinite")
    edit_state(model_dir, lambda s: s["readout.weight"].fill_(float("inf")))
    refused(arch, model_dir, "NaN or infinite")


def test_zero_input_scale(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    edit_state(model_dir, lambda s: s["input_scale"][:3].zero_())
    refused(arch, model_dir, r"input_scale holds 3 zero or negative")


def test_all_zero_linear_weights(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    edit_state(model_dir, lambda s: s["readout.weight"].zero_())
    refused(arch, model_dir, r"readout\.weight is all zero")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda m: m["config"].update(fusion_units="8"), "config.fusion_units"),
        (lambda m: m["config"].update(fusion_units=True), "config.fusion_units"),
        (lambda m: m.update(fitted="yes"), "fitted"),
        (lambda m: m.update(config=[1, 2]), "config"),
        (lambda m: m.update(inputs=["pac_code"]), "inputs"),
        (lambda m: m.update(feature_settings=[]), "feature_settings"),
        (lambda m: m["config"].update(dropout=-1.0), "config.dropout"),
        (lambda m: m["config"].update(no_such_field=1), "config.no_such_field"),
        (lambda m: m.update(modalities=["pac"]), "modalities"),
        (lambda m: m.update(classes=["a", "b"]), "classes"),
        (lambda m: m.update(unknown=1), "unknown"),
        (lambda m: m.update(format_version=2), "is not a hapticframe-recurrent-classifier v1"),
    ],
)
def test_wrong_metadata_types_and_values(
    saved: tuple[str, Path], change: Callable[[dict[str, Any]], Any], match: str
) -> None:
    arch, model_dir = saved
    edit_meta(model_dir, change)
    assert "model.json" in refused(arch, model_dir, match)


def test_metadata_that_is_not_an_object_or_holds_nan(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    (model_dir / "model.json").write_text("[1, 2]")
    refused(arch, model_dir, r"model\.json holds a JSON list, not an object")
    (model_dir / "model.json").write_text('{"format": NaN}')
    refused(arch, model_dir, "NaN")
    (model_dir / "model.json").write_text("[" * 100_000)
    refused(arch, model_dir, "model.json")


def test_huge_declared_sizes_are_refused_from_the_metadata(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    edit_meta(model_dir, lambda m: m["config"].update({WIDTH[arch]: 200000}))
    refused(arch, model_dir, rf"config\.{WIDTH[arch]}: Input should be less than or equal")
    # Within every per-field bound, but too many parameters in all.
    edit_meta(model_dir, lambda m: m["config"].update({WIDTH[arch]: 4096, DEPTH[arch]: 16}))
    refused(arch, model_dir, r"describes a network of .* parameters; the limit")


class _Payload:
    """Unpickling this would create ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[Any, ...]:
        return (Path.touch, (self.marker,))


def test_a_code_payload_is_refused_as_unsafe_without_running(
    saved: tuple[str, Path], tmp_path: Path
) -> None:
    arch, model_dir = saved
    marker = tmp_path / "ran"
    state = torch.load(model_dir / "weights.pt", weights_only=True)
    torch.save({**state, "payload": _Payload(marker)}, model_dir / "weights.pt")
    message = refused(arch, model_dir, "not a hapticframe artifact.*may be unsafe")
    assert "weights.pt" in message
    with (model_dir / "weights.pt").open("wb") as stream:
        pickle.dump(_Payload(marker), stream)
    refused(arch, model_dir, "not a hapticframe artifact.*may be unsafe")
    assert not marker.exists()


def test_a_fifo_or_directory_is_not_read(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    (model_dir / "weights.pt").unlink()
    os.mkfifo(model_dir / "weights.pt")  # reading it would block forever
    refused(arch, model_dir, r"weights\.pt is not a regular file")


def test_oversized_weights_are_refused_before_reading(saved: tuple[str, Path]) -> None:
    arch, model_dir = saved
    with (model_dir / "weights.pt").open("ab") as stream:
        stream.truncate(64 << 20)
    refused(arch, model_dir, r"weights\.pt holds \d+ bytes, more than")


# -- linear-svm -----------------------------------------------------------------------------

SVM_INPUTS = {"pac_code": 3, "pdc_code": 2}


def svm(model_dir: Path | None = None) -> LinearSVMClassifier:
    config = (LinearSVMConfig(model_dir=str(model_dir)) if model_dir
              else LinearSVMConfig(inputs=SVM_INPUTS))
    return LinearSVMClassifier(config, BuildContext("svm", np.random.default_rng(0)))


@pytest.fixture
def svm_dir(tmp_path: Path) -> Path:
    svm().save(tmp_path / "svm")
    return tmp_path / "svm"


def svm_refused(model_dir: Path, match: str) -> str:
    with pytest.raises(ValueError, match=match) as info:
        svm(model_dir)
    return str(info.value)


def rewrite_npz(model_dir: Path, **changes: Any) -> None:
    with np.load(model_dir / "model.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(model_dir / "model.npz", **arrays)


def test_svm_round_trip(svm_dir: Path) -> None:
    loaded, original = svm(svm_dir), svm()
    assert np.array_equal(loaded.coef, original.coef) and loaded.groups == SVM_INPUTS


def test_svm_truncated_empty_and_not_an_npz(svm_dir: Path) -> None:
    data = (svm_dir / "model.npz").read_bytes()
    (svm_dir / "model.npz").write_bytes(data[: len(data) // 2])
    svm_refused(svm_dir, r"model\.npz is not a readable \.npz archive")
    (svm_dir / "model.npz").write_bytes(b"")
    svm_refused(svm_dir, r"model\.npz is empty")
    np.save(svm_dir / "model.npy", np.zeros(5))
    (svm_dir / "model.npy").rename(svm_dir / "model.npz")
    svm_refused(svm_dir, r"model\.npz is not a readable \.npz archive")


def test_svm_reshaped_nan_and_degenerate_arrays(svm_dir: Path) -> None:
    rewrite_npz(svm_dir, coef=np.ones(6))
    svm_refused(svm_dir, r"model\.npz: coef has shape \(6,\), expected \(5,\)")
    rewrite_npz(svm_dir, coef=np.array([1.0, np.nan, 0, 0, 0]))
    svm_refused(svm_dir, "coef holds 1 NaN")
    rewrite_npz(svm_dir, coef=np.ones(5), spread=np.zeros(5))
    svm_refused(svm_dir, "spread holds zero")
    rewrite_npz(svm_dir, spread=np.ones(5), coef=np.zeros(5))
    svm_refused(svm_dir, "coef is zero")
    rewrite_npz(svm_dir, coef=np.array(["a"] * 5))
    svm_refused(svm_dir, "coef holds <U1 values")


def test_svm_pickled_object_array_is_not_unpickled(svm_dir: Path, tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    payload = np.array([_Payload(marker)] * 5, dtype=object)
    np.savez(svm_dir / "model.npz", coef=payload, mean=np.zeros(5), spread=np.ones(5))
    svm_refused(svm_dir, "coef holds object values")
    assert not marker.exists()


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda m: m.update(platt_a="1"), "platt_a"),
        (lambda m: m.update(platt_a=0.0), "platt_a is zero"),
        (lambda m: m.update(intercept=1e300), "intercept"),
        (lambda m: m.update(inputs=[3, 2]), "inputs"),
        (lambda m: m.update(inputs={"pac_code": 10**9}), "inputs"),
        (lambda m: m.update(config=None), "config"),
        (lambda m: m["config"].update(c="1"), "config.c"),
        (lambda m: m.update(fitted=1), "fitted"),
    ],
)
def test_svm_wrong_metadata(
    svm_dir: Path, change: Callable[[dict[str, Any]], Any], match: str
) -> None:
    edit_meta(svm_dir, change)
    assert "model.json" in svm_refused(svm_dir, match)
