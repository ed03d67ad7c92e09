"""Corrupt saved force-observer models: each is a ValueError naming the file (issue 16 §2)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import BuildContext
from hapticframe_force_observer import ForceObserver, ForceObserverConfig

Q = (0.9238795325112867, 0.0, 0.3826834323650898, 0.0)  # 45° about y
INLINE = {"mass_kg": 0.4, "imu_rotation_wxyz": Q, "bias_n": (0.1, -0.2, 0.3)}


def make(model_dir: Path | None = None) -> ForceObserver:
    config = ForceObserverConfig(model_dir=str(model_dir)) if model_dir else \
        ForceObserverConfig(**INLINE)
    return ForceObserver(config, BuildContext(id="observer", rng=np.random.default_rng(0)))


@pytest.fixture
def model_dir(tmp_path: Path) -> Path:
    """A model saved by save() from inline parameters (train-free)."""
    make().save(tmp_path / "model")
    return tmp_path / "model"


def refused(model_dir: Path, match: str) -> str:
    with pytest.raises(ValueError, match=match) as info:
        make(model_dir)
    return str(info.value)


def edit_meta(model_dir: Path, change: Callable[[dict[str, Any]], Any]) -> None:
    meta = json.loads((model_dir / "model.json").read_text())
    change(meta)
    (model_dir / "model.json").write_text(json.dumps(meta))


def rewrite_npz(model_dir: Path, **changes: Any) -> None:
    with np.load(model_dir / "model.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(model_dir / "model.npz", **arrays)


def test_round_trip(model_dir: Path) -> None:
    loaded, original = make(model_dir), make()
    assert loaded.parameters.mass_kg == original.parameters.mass_kg
    assert np.array_equal(loaded.parameters.rotation, original.parameters.rotation)


def test_truncated_and_empty_files(model_dir: Path) -> None:
    data = (model_dir / "model.npz").read_bytes()
    (model_dir / "model.npz").write_bytes(data[: len(data) // 2])
    assert "model.npz is not a readable .npz" in refused(model_dir, "truncated")
    (model_dir / "model.npz").write_bytes(b"")
    refused(model_dir, r"model\.npz is empty")
    text = (model_dir / "model.json").read_text()
    (model_dir / "model.json").write_text(text[:40])
    refused(model_dir, r"model\.json is not valid JSON")
    (model_dir / "model.json").write_bytes(b"")
    refused(model_dir, r"model\.json is empty")


def test_reshaped_and_retyped_arrays(model_dir: Path) -> None:
    rewrite_npz(model_dir, rotation=np.eye(3).ravel())
    refused(model_dir, r"model\.npz: rotation has shape \(9,\), expected \(3, 3\)")
    rewrite_npz(model_dir, rotation=np.eye(3, dtype=np.int64))
    refused(model_dir, r"model\.npz: rotation holds int64 values")
    rewrite_npz(model_dir, rotation=np.eye(3, dtype=object))
    refused(model_dir, "rotation holds object values")


def test_nan_arrays(model_dir: Path) -> None:
    with np.load(model_dir / "model.npz") as data:
        bias = data["bias_n"].copy()
    bias[1] = np.nan
    rewrite_npz(model_dir, bias_n=bias)
    refused(model_dir, r"model\.npz: bias_n holds 1 NaN or infinite")


def test_files_from_different_models(model_dir: Path) -> None:
    rewrite_npz(model_dir, bias_n=np.zeros(3))
    refused(model_dir, r"bias_n in model\.npz .* differs from model\.json")
    rewrite_npz(model_dir, bias_n=np.array(INLINE["bias_n"]), rotation=np.eye(3))
    refused(model_dir, "rotation in model.npz differs")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda m: m.update(mass_kg="0.4"), "mass_kg"),
        (lambda m: m.update(mass_kg=True), "mass_kg"),
        (lambda m: m.update(mass_kg=1e300), "mass_kg"),
        (lambda m: m.update(rotation_wxyz=[1.0, 0.0, 0.0]), "rotation_wxyz"),
        (lambda m: m.update(rotation_wxyz=[2.0, 0.0, 0.0, 0.0]), "unit quaternion"),
        (lambda m: m.update(bias_n={"x": 0.1}), "bias_n"),
        (lambda m: m.update(filter=[10.0, 2, 100.0]), "filter"),
        (lambda m: m.update(training_report=[]), "training_report"),
        (lambda m: m.update(channels="force_n"), "channels"),
        (lambda m: m.update(extra=1), "extra"),
        (lambda m: m.pop("mass_kg"), "mass_kg"),
    ],
)
def test_wrong_metadata_types_and_values(
    model_dir: Path, change: Callable[[dict[str, Any]], Any], match: str
) -> None:
    edit_meta(model_dir, change)
    assert "model.json" in refused(model_dir, match)


def test_metadata_that_is_a_list_or_holds_nan(model_dir: Path) -> None:
    (model_dir / "model.json").write_text("[]")
    refused(model_dir, "holds a JSON list, not an object")
    (model_dir / "model.json").write_text(
        '{"format": "hapticframe-force-observer", "format_version": 1, "mass_kg": NaN}')
    refused(model_dir, "NaN")


def test_a_pickle_payload_is_not_unpickled(model_dir: Path, tmp_path: Path) -> None:
    class Payload:
        def __reduce__(self) -> tuple[Any, ...]:
            return (Path.touch, (tmp_path / "ran",))

    np.savez(model_dir / "model.npz", rotation=np.array([Payload()] * 9, dtype=object),
             bias_n=np.zeros(3))
    refused(model_dir, "rotation holds object values")
    assert not (tmp_path / "ran").exists()


def test_a_fifo_and_an_oversized_file_are_not_read(model_dir: Path) -> None:
    (model_dir / "model.json").unlink()
    os.mkfifo(model_dir / "model.json")
    refused(model_dir, r"model\.json is not a regular file")
    (model_dir / "model.json").unlink()
    make().save(model_dir)
    with (model_dir / "model.npz").open("ab") as stream:
        stream.truncate(8 << 20)
    refused(model_dir, r"model\.npz holds \d+ bytes, more than")
