"""The amplitude channel: ``sparse-coding`` with ``amplitude="channel"`` and the recurrent
classifiers with ``amplitude_inputs`` (a deviation from the thesis, see the configs).

The coder's unit-norm scaling makes codes blind to a tensor's size; the amplitude channel
carries that size. Checked here: the values against a direct formula, scale behaviour,
extremes, streaming = batch, fit/save/load of the reference, and on the classifier side
shapes, streaming = batch, a modality's code and amplitude zero-filled together, and the
save/load round trip.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, SampleBatch

torch = pytest.importorskip("torch")
pytest.importorskip("sklearn")

from hapticframe_sfrnn import (  # noqa: E402
    FusionRNNClassifier,
    FusionRNNConfig,
    SFRNNClassifier,
    SFRNNConfig,
)
from hapticframe_tactile_features import SparseCodingConfig, SparseCodingExtractor  # noqa: E402

# The amplitude formula itself has no public name; the test checks it directly.
from hapticframe_tactile_features._sparse import (  # noqa: E402
    amplitude_features,
    amplitude_reference,
)

SHAPES = {"pac_imfs": (8, 22), "pdc_imfs": (5, 5), "electrodes_window": (19, 5)}
SMALL = {"pac_atoms": 12, "pdc_atoms": 8, "electrodes_atoms": 8, "fit_epochs": 1}


def _context(seed: int = 0) -> BuildContext:
    return BuildContext("c", np.random.default_rng(seed))


def _coder(seed: int = 0, **config: object) -> SparseCodingExtractor:
    return SparseCodingExtractor(SparseCodingConfig(**{**SMALL, **config}), _context(seed))


def _tensors(rng: np.random.Generator, n: int, scale: float = 1.0) -> SampleBatch:
    return SampleBatch(
        (1 + np.arange(n)) / 100.0,
        {k: scale * rng.standard_normal((n, *s)) for k, s in SHAPES.items()},
    )


# -- the features --------------------------------------------------------------------------


def test_amplitude_features_match_the_formula_and_zero_invalid_rows() -> None:
    rng = np.random.default_rng(0)
    rows = rng.standard_normal((6, 30)) * 5 + 2
    ok = np.array([True, True, False, True, True, True])
    got = amplitude_features(rows, ok, 3.0)
    mean = rows.mean(axis=1)
    norm = np.linalg.norm(rows - mean[:, None], axis=1)
    expected = np.column_stack([np.log1p(norm / 3.0) - np.log(2.0), np.arcsinh(mean / 3.0)])
    np.testing.assert_allclose(got[ok], expected[ok], rtol=1e-12, atol=1e-12)
    assert np.array_equal(got[2], [0.0, 0.0])
    # A row of the reference size and zero mean reads 0: "typical".
    typical = np.zeros((1, 4))
    typical[0, :2] = [1.0, -1.0]
    assert np.allclose(amplitude_features(typical, np.ones(1, bool), np.sqrt(2.0)), 0.0)
    # Size, unlike the unit-norm code, is seen: a larger copy has a larger log-norm.
    assert amplitude_features(4 * rows[:1], ok[:1], 3.0)[0, 0] > got[0, 0]


def test_amplitude_features_stay_finite_at_extremes() -> None:
    rows = np.array([[1e300, -1e300, 5e299], [1e-300, 0.0, -1e-300], [0.0, 0.0, 0.0],
                     [7.0, 7.0, 7.0], [np.nan, 1.0, np.inf]])  # fmt: skip
    ok = np.array([True, True, True, True, False])
    out = amplitude_features(rows, ok, 1e-3)
    assert np.isfinite(out).all()
    assert out[0, 0] > 600 and out[2, 0] == pytest.approx(-np.log(2.0))
    assert out[3, 0] == pytest.approx(-np.log(2.0)) and out[3, 1] > 0  # constant: no norm
    assert np.array_equal(out[4], [0.0, 0.0])
    with pytest.raises(ValueError, match="positive"):
        amplitude_features(rows, ok, 0.0)
    with pytest.raises(ValueError, match="positive"):
        amplitude_features(rows, ok, np.nan)


def test_amplitude_reference_is_the_median_centred_norm() -> None:
    rows = np.array([[1.0, -1.0], [2.0, -2.0], [3.0, -3.0], [5.0, 5.0], [np.nan, 0.0]])
    # The constant row and the non-finite one are left out.
    assert amplitude_reference(rows) == pytest.approx(2.0 * np.sqrt(2.0))
    assert amplitude_reference(np.zeros((3, 4))) == 1.0


# -- the coder -----------------------------------------------------------------------------


def test_coder_emits_amplitude_only_when_asked() -> None:
    rng = np.random.default_rng(1)
    batch = _tensors(rng, 7)
    thesis = _coder()
    assert sorted(thesis.output_channels) == ["electrodes_code", "pac_code", "pdc_code"]
    assert sorted(thesis.update(batch).channels) == ["electrodes_code", "pac_code", "pdc_code"]
    coder = _coder(amplitude="channel")
    assert coder.output_channels["pdc_amplitude"].shape == (2,)
    out = coder.update(batch)
    for m in ("pac", "pdc", "electrodes"):
        assert out.channels[f"{m}_amplitude"].shape == (7, 2)
        # The codes themselves are the thesis's, unchanged by the option.
        assert np.array_equal(out.channels[f"{m}_code"], thesis.update(batch).channels[f"{m}_code"])
    # Scaling the tensors leaves the codes and moves the amplitude.
    bigger = coder.update(_tensors(np.random.default_rng(1), 7, scale=10.0))
    np.testing.assert_allclose(bigger.channels["pac_code"], out.channels["pac_code"], atol=1e-9)
    assert (bigger.channels["pac_amplitude"][:, 0] > out.channels["pac_amplitude"][:, 0]).all()


def test_coder_amplitude_streams_like_the_batch_and_flags_invalid_tensors() -> None:
    rng = np.random.default_rng(2)
    batch = _tensors(rng, 12)
    bad = batch.channels["electrodes_window"].copy()
    bad[4, 0, 0] = np.nan
    batch = SampleBatch(batch.timestamps_s, {**batch.channels, "electrodes_window": bad},
                        {"pac_imfs": np.arange(12) != 6})  # fmt: skip
    coder = _coder(amplitude="channel")
    whole = coder.update(batch)
    parts = [coder.update(batch.select(slice(a, b))) for a, b in ((0, 1), (1, 5), (5, 12))]
    for name, values in whole.channels.items():
        assert np.array_equal(np.vstack([p.channels[name] for p in parts]), values)
    assert np.array_equal(whole.channels["electrodes_amplitude"][4], [0.0, 0.0])
    assert not whole.valid["electrodes_amplitude"][4] and whole.valid["electrodes_amplitude"][3]
    assert not whole.valid["pac_amplitude"][6]
    assert np.isfinite(whole.channels["electrodes_amplitude"]).all()


def test_fit_learns_the_reference_and_save_load_keeps_it(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    coder = _coder(seed=1, amplitude="channel")
    assert coder.amplitude_references == {"pac": 1.0, "pdc": 1.0, "electrodes": 1.0}
    train = _tensors(rng, 200, scale=4.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        coder.fit([train])
    rows = train.channels["pdc_imfs"].reshape(200, -1)
    expected = np.median(np.linalg.norm(rows - rows.mean(axis=1, keepdims=True), axis=1))
    assert coder.amplitude_references["pdc"] == pytest.approx(expected)
    # Typical training tensors now read about 0 on the log-norm.
    log_norm = coder.update(train).channels["pdc_amplitude"][:, 0]
    assert abs(np.median(log_norm)) < 0.05
    _, meta_path = coder.save(tmp_path / "d")
    meta = json.loads(meta_path.read_text())
    assert meta["format_version"] == 2 and meta["amplitude"]["mode"] == "channel"
    assert meta["amplitude"]["reference"]["pdc"] == pytest.approx(expected)
    loaded = _coder(seed=9, amplitude="channel", dictionary_file=str(tmp_path / "d"))
    assert loaded.amplitude_references == pytest.approx(coder.amplitude_references)
    probe = _tensors(rng, 5)
    for name, values in coder.update(probe).channels.items():
        assert np.array_equal(loaded.update(probe).channels[name], values)
    # A version-1 file (no references) still loads, with unit references.
    with np.load(tmp_path / "d.npz") as data:
        np.savez(tmp_path / "old.npz", **{k: data[k] for k in data.files if "reference" not in k})
    (tmp_path / "old.json").write_text(json.dumps({**meta, "format_version": 1}))
    old = _coder(amplitude="channel", dictionary_file=str(tmp_path / "old"))
    assert old.amplitude_references == {"pac": 1.0, "pdc": 1.0, "electrodes": 1.0}


# -- the classifiers -----------------------------------------------------------------------

CODE_SIZES = {"pac_code_size": 6, "pdc_code_size": 4, "electrodes_code_size": 5}
TINY = {"fusion_units": 8, "gru_layers": 1, "gru_units": 8, "max_epochs": 3, "progress": False,
        "window_frames": 20, "batch_size": 16}  # fmt: skip


def _trial(rng: np.random.Generator, n: int = 120) -> tuple[SampleBatch, np.ndarray]:
    """Codes of unit-norm-like noise; contact is visible in the electrodes' amplitude only."""
    labels = np.zeros(n, dtype=int)
    start = int(rng.integers(20, n - 40))
    labels[start : start + 30] = 1
    channels = {}
    for m, size in (("pac", 6), ("pdc", 4), ("electrodes", 5)):
        code = rng.standard_normal((n, size)) * (rng.random((n, size)) < 0.4)
        channels[f"{m}_code"] = code
        amp = 0.2 * rng.standard_normal((n, 2))
        if m == "electrodes":
            amp[:, 0] += 1.5 * labels
        channels[f"{m}_amplitude"] = amp
    return SampleBatch((1 + np.arange(n)) / 100.0, channels), labels


@pytest.fixture(scope="module")
def trained() -> tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]]:
    rng = np.random.default_rng(4)
    data = [_trial(rng) for _ in range(14)]
    config = SFRNNConfig(**CODE_SIZES, **{**TINY, "max_epochs": 8}, amplitude_inputs=True)
    clf = SFRNNClassifier(config, _context(0))
    clf.fit([b for b, _ in data[:10]], [y for _, y in data[:10]])
    return clf, data[10:]


def test_sfrnn_with_amplitude_shapes_and_learning(
    trained: tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]],
) -> None:
    clf, test = trained
    assert list(clf.groups) == ["pac_code", "pac_amplitude", "pdc_code", "pdc_amplitude",
                                "electrodes_code", "electrodes_amplitude"]  # fmt: skip
    assert clf.modality_sizes == [8, 6, 7] and clf.net.group_sizes == [8, 6, 7]
    assert clf.net.fusion.in_features == 21
    # The amplitude columns carry the gain: scale = RMS / gain there, RMS for the codes.
    scale = clf.net.input_scale.numpy()
    assert scale.shape == (21,)
    assert scale[6] == pytest.approx(scale[7])  # one scale per channel
    assert clf.config.amplitude_gain == 30.0
    predicted = np.concatenate([clf.predict(b) for b, _ in test])
    truth = np.concatenate([y for _, y in test])
    recall = [np.mean(predicted[truth == c] == c) for c in (0, 1)]
    assert np.mean(recall) >= 0.8  # only the amplitude separates the classes here


def test_amplitude_gain_sets_the_input_scale() -> None:
    rng = np.random.default_rng(5)
    data = [_trial(rng) for _ in range(6)]
    scales = {}
    for gain in (1.0, 4.0):
        clf = SFRNNClassifier(
            SFRNNConfig(**CODE_SIZES, **{**TINY, "max_epochs": 1}, amplitude_inputs=True,
                        amplitude_gain=gain),
            _context(0),
        )  # fmt: skip
        clf.fit([b for b, _ in data], [y for _, y in data])
        scales[gain] = clf.net.input_scale.numpy().copy()
    ratio = scales[1.0] / scales[4.0]
    amplitude_cols = np.r_[6:8, 12:14, 19:21]
    code_cols = np.setdiff1d(np.arange(21), amplitude_cols)
    np.testing.assert_allclose(ratio[amplitude_cols], 4.0)
    np.testing.assert_allclose(ratio[code_cols], 1.0)
    all_amp = np.vstack([b.channels["pac_amplitude"] for b, _ in data])
    assert scales[1.0][6] == pytest.approx(np.sqrt(np.mean(all_amp**2)))


def test_sfrnn_with_amplitude_streams_like_the_batch(
    trained: tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]],
) -> None:
    clf, test = trained
    batch, _ = test[0]
    whole = clf.predict_proba(batch).probabilities
    clf.reset()
    parts = [clf.update(batch.select(slice(a, b))).probabilities
             for a, b in ((0, 1), (1, 33), (33, len(batch)))]  # fmt: skip
    assert np.max(np.abs(np.vstack(parts) - whole)) <= 1e-6
    sequence = clf.predict_sequence(batch).probabilities
    assert np.max(np.abs(sequence - whole)) <= 1e-5


def test_a_modality_is_its_code_and_amplitude_together(
    trained: tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]],
) -> None:
    clf, test = trained
    batch, _ = test[1]
    ch = batch.channels

    def without(*names: str) -> SampleBatch:
        return SampleBatch(batch.timestamps_s, {k: v for k, v in ch.items() if k not in names})

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        both = clf.predict_proba(without("electrodes_code", "electrodes_amplitude")).probabilities
        no_amp = clf.predict_proba(without("electrodes_amplitude")).probabilities
        no_code = clf.predict_proba(without("electrodes_code")).probabilities
    assert np.array_equal(both, no_amp) and np.array_equal(both, no_code)
    assert not np.array_equal(both, clf.predict_proba(batch).probabilities)
    # Invalid amplitude in some frames zero-fills the code of those frames too.
    valid = np.ones(len(batch), bool)
    valid[10:40] = False
    flagged = SampleBatch(batch.timestamps_s, dict(ch), {"electrodes_amplitude": valid})
    zeroed = {**ch}
    for name in ("electrodes_code", "electrodes_amplitude"):
        zeroed[name] = ch[name].copy()
        zeroed[name][10:40] = 0.0
    expected = clf.predict_proba(SampleBatch(batch.timestamps_s, zeroed)).probabilities
    assert np.array_equal(clf.predict_proba(flagged).probabilities, expected)


def test_save_load_round_trip_with_amplitude(
    trained: tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]], tmp_path: Path
) -> None:
    clf, test = trained
    batch, _ = test[0]
    expected = clf.predict_proba(batch).probabilities
    clf.save(tmp_path / "m")
    meta = json.loads((tmp_path / "m" / "model.json").read_text())
    assert meta["inputs"]["electrodes_amplitude"] == 2
    assert meta["modality_inputs"]["pdc"] == ["pdc_code", "pdc_amplitude"]
    loaded = SFRNNClassifier(SFRNNConfig(model_dir=str(tmp_path / "m")), _context(7))
    assert loaded.config.amplitude_inputs and loaded.groups == clf.groups
    assert np.array_equal(loaded.predict_proba(batch).probabilities, expected)


def test_fusion_rnn_gives_each_modality_one_branch_with_its_amplitude() -> None:
    rng = np.random.default_rng(6)
    data = [_trial(rng) for _ in range(6)]
    config = FusionRNNConfig(**CODE_SIZES, branch_layers=1, branch_units=4, fusion_units=4,
                             max_epochs=1, progress=False, window_frames=20,
                             amplitude_inputs=True)  # fmt: skip
    clf = FusionRNNClassifier(config, _context(1))
    assert len(clf.net.branches) == 3
    assert [b.layers[0].input_size for b in clf.net.branches] == [8, 6, 7]
    clf.fit([b for b, _ in data], [y for _, y in data])
    proba = clf.predict_proba(data[0][0]).probabilities
    assert proba.shape == (120, 2) and np.isfinite(proba).all()


def test_amplitude_modalities_narrow_what_is_read(
    trained: tuple[SFRNNClassifier, list[tuple[SampleBatch, np.ndarray]]], tmp_path: Path
) -> None:
    _, test = trained
    rng = np.random.default_rng(8)
    data = [_trial(rng) for _ in range(6)]
    config = SFRNNConfig(**CODE_SIZES, **{**TINY, "max_epochs": 1}, amplitude_inputs=True,
                         amplitude_modalities=("electrodes", "pdc"))  # fmt: skip
    assert config.amplitude_modalities == ("pdc", "electrodes")  # canonical order
    assert not config.reads_amplitude("pac") and config.reads_amplitude("pdc")
    clf = SFRNNClassifier(config, _context(0))
    assert list(clf.groups) == ["pac_code", "pdc_code", "pdc_amplitude", "electrodes_code",
                                "electrodes_amplitude"]  # fmt: skip
    assert clf.modality_sizes == [6, 6, 7] and clf.net.fusion.in_features == 19
    clf.fit([b for b, _ in data], [y for _, y in data])
    batch, _ = test[0]
    expected = clf.predict_proba(batch).probabilities
    # pac's amplitude is not an input: changed or absent, nothing changes and nothing warns.
    louder = 50.0 + batch.channels["pac_amplitude"]
    changed = SampleBatch(batch.timestamps_s, {**batch.channels, "pac_amplitude": louder})
    dropped = SampleBatch(batch.timestamps_s, {k: v for k, v in batch.channels.items()
                                                if k != "pac_amplitude"})  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        assert np.array_equal(clf.predict_proba(changed).probabilities, expected)
        assert np.array_equal(clf.predict_proba(dropped).probabilities, expected)
    # ... while the electrodes' amplitude still is.
    moved = SampleBatch(batch.timestamps_s, {**batch.channels, "electrodes_amplitude":
                                              batch.channels["electrodes_amplitude"] + 3.0})
    assert not np.array_equal(clf.predict_proba(moved).probabilities, expected)
    clf.save(tmp_path / "m")
    loaded = SFRNNClassifier(SFRNNConfig(model_dir=str(tmp_path / "m")), _context(3))
    assert loaded.config.amplitude_modalities == ("pdc", "electrodes")
    assert loaded.groups == clf.groups
    assert np.array_equal(loaded.predict_proba(batch).probabilities, expected)
    with pytest.raises(ValueError, match="repeat"):
        SFRNNConfig(amplitude_inputs=True, amplitude_modalities=("pdc", "pdc"))
    # Without amplitude_inputs the list changes nothing.
    plain = SFRNNConfig(**CODE_SIZES, amplitude_modalities=("pdc",))
    assert plain.input_groups("pdc") == {"pdc_code": 4}
