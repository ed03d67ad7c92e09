"""Corrupt saved sparse-coding dictionaries: each is a ValueError naming the file (issue 16 §2)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import BuildContext
from hapticframe_tactile_features import SparseCodingConfig, SparseCodingExtractor

SMALL = {"pac_atoms": 6, "pdc_atoms": 4, "electrodes_atoms": 5, "amplitude": "channel"}


def coder(dictionary_file: Path | None = None, seed: int = 0) -> SparseCodingExtractor:
    config = SparseCodingConfig(
        **SMALL, dictionary_file=str(dictionary_file) if dictionary_file else None)
    return SparseCodingExtractor(config, BuildContext("codes", np.random.default_rng(seed)))


@pytest.fixture
def saved(tmp_path: Path) -> Path:
    """Random unit-norm dictionaries saved by save() (train-free), in a directory."""
    (tmp_path / "codes").mkdir()
    coder().save(tmp_path / "codes")
    return tmp_path / "codes"


def refused(directory: Path, match: str) -> str:
    with pytest.raises(ValueError, match=match) as info:
        coder(directory, seed=1)
    message = str(info.value)
    assert "dictionaries." in message and len(message) < 1000
    return message


def edit_meta(directory: Path, change: Callable[[dict[str, Any]], Any]) -> None:
    path = directory / "dictionaries.json"
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))


def rewrite_npz(directory: Path, **changes: Any) -> None:
    with np.load(directory / "dictionaries.npz") as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(changes)
    np.savez(directory / "dictionaries.npz", **arrays)


def test_round_trip(saved: Path) -> None:
    loaded, original = coder(saved, seed=1), coder()
    for m in ("pac", "pdc", "electrodes"):
        assert np.array_equal(loaded.dictionaries[m], original.dictionaries[m])


def test_truncated_and_empty_files(saved: Path) -> None:
    data = (saved / "dictionaries.npz").read_bytes()
    (saved / "dictionaries.npz").write_bytes(data[: len(data) // 2])
    refused(saved, r"dictionaries\.npz is not a readable \.npz archive \(truncated")
    (saved / "dictionaries.npz").write_bytes(b"")
    refused(saved, r"dictionaries\.npz is empty")
    text = (saved / "dictionaries.json").read_text()
    (saved / "dictionaries.json").write_text(text[: len(text) // 3])
    refused(saved, r"dictionaries\.json is not valid JSON")
    (saved / "dictionaries.json").write_text("")
    refused(saved, r"dictionaries\.json is empty")


def test_reshaped_arrays(saved: Path) -> None:
    rewrite_npz(saved, pdc_dictionary=np.ones((5, 25)) / 5.0)
    refused(saved, r"pdc_dictionary has shape \(5, 25\), expected \(4, 25\)")
    rewrite_npz(saved, pdc_dictionary=np.ones((4, 25)) / 5.0, pac_amplitude_reference=np.ones(2))
    refused(saved, r"pac_amplitude_reference has shape \(2,\), expected \(\)")


def test_metadata_that_declares_another_shape(saved: Path) -> None:
    edit_meta(saved, lambda m: m["atoms"].update(pac=7))
    refused(saved, r"dictionaries\.json: the pac dictionary has shape \(7, 176\)")


def test_nan_values(saved: Path) -> None:
    with np.load(saved / "dictionaries.npz") as data:
        d = data["pac_dictionary"].copy()
    d[2, 3] = np.nan
    rewrite_npz(saved, pac_dictionary=d)
    refused(saved, r"dictionaries\.npz: pac_dictionary holds 1 NaN or infinite")
    rewrite_npz(saved, pac_dictionary=np.nan_to_num(d), pdc_amplitude_reference=np.array(np.inf))
    refused(saved, "pdc_amplitude_reference holds 1 NaN")


def test_degenerate_dictionaries(saved: Path) -> None:
    with np.load(saved / "dictionaries.npz") as data:
        d = data["electrodes_dictionary"].copy()
    rewrite_npz(saved, electrodes_dictionary=np.zeros_like(d))
    refused(saved, r"electrodes_dictionary has 5 atom\(s\) of zero norm")
    rewrite_npz(saved, electrodes_dictionary=d * 3.0)
    refused(saved, "norm above 1")
    rewrite_npz(saved, electrodes_dictionary=np.repeat(d[:1], 5, axis=0))
    refused(saved, "every atom of electrodes_dictionary is the same")
    rewrite_npz(saved, electrodes_dictionary=d, pac_amplitude_reference=np.array(0.0))
    refused(saved, "pac_amplitude_reference must be positive")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda m: m.update(atoms=[6, 4, 5]), "atoms"),
        (lambda m: m["atoms"].update(pac="6"), "atoms.pac"),
        (lambda m: m["atoms"].update(pac=True), "atoms.pac"),
        (lambda m: m["atoms"].update(pac=200000), "atoms.pac"),
        (lambda m: m["tensor_shapes"].update(pac=[8, 22, 1]), "tensor_shapes.pac"),
        (lambda m: m.update(lambda_scale="1.2"), "lambda_scale"),
        (lambda m: m.update(fitted="no"), "fitted"),
        (lambda m: m.update(modalities="pac"), "modalities"),
        (lambda m: m.update(fit=[]), "fit"),
        (lambda m: m.update(lambda_scale=2.0), "lambda_scale 2.0, the config says 1.2"),
        (lambda m: m.update(format_version=3), "unsupported dictionary format version 3"),
    ],
)
def test_wrong_metadata_types_and_values(
    saved: Path, change: Callable[[dict[str, Any]], Any], match: str
) -> None:
    edit_meta(saved, change)
    assert "dictionaries.json" in refused(saved, match)


def test_huge_declared_sizes_are_refused_from_the_metadata(saved: Path) -> None:
    edit_meta(saved, lambda m: m["tensor_shapes"].update(pac=[50_000, 50_000]))
    refused(saved, r"the pac dictionary would hold 1\.5e\+10 values; the limit")


def test_a_pickle_payload_is_not_unpickled(saved: Path, tmp_path: Path) -> None:
    class Payload:
        def __reduce__(self) -> tuple[Any, ...]:
            return (Path.touch, (tmp_path / "ran",))

    rewrite_npz(saved, pac_dictionary=np.array([[Payload()] * 176] * 6, dtype=object))
    refused(saved, "pac_dictionary holds object values")
    assert not (tmp_path / "ran").exists()


def test_a_fifo_and_an_oversized_file_are_not_read(saved: Path) -> None:
    with (saved / "dictionaries.npz").open("ab") as stream:
        stream.truncate(16 << 20)
    refused(saved, r"dictionaries\.npz holds \d+ bytes, more than")
    (saved / "dictionaries.json").unlink()
    os.mkfifo(saved / "dictionaries.json")
    refused(saved, r"dictionaries\.json is not a regular file")
