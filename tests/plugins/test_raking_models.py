"""The authors' Keras models read with h5py, the numpy LSTM against torch's, and the
shipped real trials against the authors' workbook (when the workbook is at hand)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe_raking import (
    INPUT_SETS,
    AuthorsModels,
    KerasModelError,
    LSTMLayer,
    authors_models_dir,
    load_keras_model,
    load_trials,
    select_inputs,
    strip_keras_model,
    windows,
)

h5py = pytest.importorskip("h5py")

REAL = Path("/work/shared/realdata/raking-3d-localization")


def test_numpy_lstm_matches_torch() -> None:
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(0)
    net = torch.nn.LSTM(3, 6, batch_first=True).double()
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(torch.from_numpy(rng.normal(0, 0.8, p.shape)))
    x = rng.normal(0, 2.0, (4, 7, 3))
    want = net(torch.from_numpy(x))[0].detach().numpy()
    layer = LSTMLayer(net.weight_ih_l0.detach().numpy().T, net.weight_hh_l0.detach().numpy().T,
                      (net.bias_ih_l0 + net.bias_hh_l0).detach().numpy())
    np.testing.assert_allclose(layer.sequence(x), want, rtol=1e-12, atol=1e-12)


def test_lstm_extremes_stay_finite() -> None:
    rng = np.random.default_rng(1)
    layer = LSTMLayer(rng.normal(size=(2, 8)), rng.normal(size=(2, 8)), rng.normal(size=8))
    for fill in (1e300, -1e300, 0.0):
        assert np.all(np.isfinite(layer.sequence(np.full((1, 5, 2), fill))))
    assert layer.sequence(np.empty((0, 5, 2))).shape == (0, 5, 2)


#: The architectures of the authors' train_main.py, per task.
ARCHITECTURES = {
    "direction": ["LSTM(units=20, return_sequences=True)", "Dense(units=3, activation='softmax')"],
    "depth": ["LSTM(units=20, return_sequences=True)", "Dense(units=1, activation='sigmoid')"],
    "distance": ["LSTM(units=100, return_sequences=True)",
                 "LSTM(units=50, return_sequences=True)", "Dense(units=1, activation='linear')"],
}


@pytest.mark.parametrize("input_set", list(INPUT_SETS))
def test_shipped_authors_models_have_train_main_architecture(input_set: str) -> None:
    for task, layers in ARCHITECTURES.items():
        model = load_keras_model(authors_models_dir() / f"{input_set}_{task}_model.h5")
        assert model.describe() == layers
        assert model.input_shape == (5, len(INPUT_SETS[input_set]))


def test_authors_distance_model_layer_by_layer_against_torch() -> None:
    torch = pytest.importorskip("torch")
    model = load_keras_model(authors_models_dir() / "4_3-axis_distance_model.h5")
    trial = load_trials("testing")[0]
    x = windows(select_inputs(trial.force, "4_3-axis"), 5, pad=False)
    h = torch.from_numpy(x)
    for layer in model.layers[:2]:
        assert isinstance(layer, LSTMLayer)
        net = torch.nn.LSTM(layer.input_size, layer.units, batch_first=True).double()
        with torch.no_grad():
            net.weight_ih_l0.copy_(torch.from_numpy(layer.kernel.T))
            net.weight_hh_l0.copy_(torch.from_numpy(layer.recurrent.T))
            net.bias_ih_l0.copy_(torch.from_numpy(layer.bias))
            net.bias_hh_l0.zero_()
            h = net(h)[0]
        np.testing.assert_allclose(layer.sequence(x), h.numpy(), atol=1e-12)
        x = h.numpy()
    dense = model.layers[2]
    want = x @ dense.kernel + dense.bias  # type: ignore[union-attr]
    got = model(windows(select_inputs(trial.force, "4_3-axis"), 5, pad=False))
    np.testing.assert_allclose(got, want, atol=1e-10)


def test_authors_estimate_scores_the_windows_last_steps() -> None:
    models = AuthorsModels.load("1_3-axis")
    trial = load_trials("testing")[3]
    est = models.estimate_trial(select_inputs(trial.force, "1_3-axis"))
    assert est.distance_mm.shape == (len(trial) - 4,)
    np.testing.assert_allclose(est.depth_proba.sum(axis=1), 1.0)
    x = windows(select_inputs(trial.force, "1_3-axis"), 5, pad=False)
    np.testing.assert_allclose(est.direction_proba, models.direction(x)[:, -1])


def _tiny_keras(path: Path, layer_class: str = "LSTM", activation: str = "tanh") -> None:
    config = {"class_name": "Sequential", "config": {"layers": [
        {"class_name": "InputLayer", "config": {"batch_input_shape": [None, 5, 2]}},
        {"class_name": layer_class, "config": {"name": "lstm", "units": 1,
                                               "activation": activation,
                                               "recurrent_activation": "sigmoid",
                                               "return_sequences": True}}]}}
    with h5py.File(path, "w") as f:
        f.attrs["model_config"] = json.dumps(config)
        g = f.create_group("model_weights").create_group("lstm")
        g.attrs["weight_names"] = [b"k", b"r", b"b"]
        g["k"], g["r"], g["b"] = np.ones((2, 4)), np.ones((1, 4)), np.zeros(4)


def test_keras_loader_refuses_what_it_cannot_run(tmp_path: Path) -> None:
    _tiny_keras(tmp_path / "ok.h5")
    assert load_keras_model(tmp_path / "ok.h5").describe() == [
        "LSTM(units=1, return_sequences=True)"]
    _tiny_keras(tmp_path / "gru.h5", layer_class="GRU")
    with pytest.raises(KerasModelError, match="is a GRU; only LSTM and Dense"):
        load_keras_model(tmp_path / "gru.h5")
    _tiny_keras(tmp_path / "relu.h5", activation="relu")
    with pytest.raises(KerasModelError, match="activation='relu'"):
        load_keras_model(tmp_path / "relu.h5")
    (tmp_path / "not.h5").write_bytes(b"nothing")
    with pytest.raises(KerasModelError, match="not a readable HDF5"):
        load_keras_model(tmp_path / "not.h5")


def test_shipped_trials_and_what_the_positions_are() -> None:
    from scipy.optimize import least_squares

    training, testing = load_trials("training"), load_trials("testing")
    assert (len(training), len(testing)) == (80, 20)
    for trial in training + testing:
        # The labels are one class per trial.
        assert len(set(trial.direction)) == 1 and len(set(trial.depth)) == 1
        # Rows 16-18: x and z stay put, y runs along the rake, 1.0-1.7 mm per step.
        x, y = trial.position_m[:, 0], trial.position_m[:, 1]
        assert np.ptp(x) < 0.002 and np.ptp(trial.position_m[:, 2]) < 0.002
        assert 1.0 < np.median(-np.diff(y) * 1000) < 1.7
        # The labelled distance is the tool's distance in the plane, in mm, to one point
        # per trial: the positions are metres in the frame of the labels.
        d = trial.distance_mm

        def residual(p: np.ndarray, x: np.ndarray = x, y: np.ndarray = y,
                     d: np.ndarray = d) -> np.ndarray:
            return np.hypot(y - p[0], x - p[1]) * 1000 - d

        fit = least_squares(residual, [y[-1] - d[-1] / 1000, x.mean()])
        assert np.abs(fit.fun).max() < 0.1, trial.name


@pytest.mark.skipif(not REAL.is_dir(), reason="the authors' workbooks are not at hand")
def test_shipped_trials_equal_an_independent_read_of_the_workbook() -> None:
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.load_workbook(REAL / "dataset/normalized_testing_dataset.xlsx",
                                  read_only=True, data_only=True)
    trials = load_trials("testing")
    assert [t.name for t in trials] == book.sheetnames
    for trial in trials[:5]:
        rows = [list(r) for r in book[trial.name].iter_rows(values_only=True)]
        n = len(trial)
        np.testing.assert_array_equal(
            trial.force.reshape(n, 12), np.array([r[:n] for r in rows[:12]], float).T)
        np.testing.assert_array_equal(trial.distance_mm, np.array(rows[21][:n], float))
        np.testing.assert_array_equal(trial.position_m, np.array([r[:n] for r in rows[15:18]],
                                                                 float).T)
    book.close()


@pytest.mark.skipif(not REAL.is_dir(), reason="the authors' models are not at hand")
def test_stripped_models_keep_the_weights_bit_for_bit(tmp_path: Path) -> None:
    source = REAL / "trained_models/1_norm/1_norm_direction_model.h5"
    strip_keras_model(source, tmp_path / "m.h5")
    a, b = load_keras_model(source), load_keras_model(tmp_path / "m.h5")
    for x, y in zip(a.layers, b.layers, strict=True):
        np.testing.assert_array_equal(x.kernel, y.kernel)
        np.testing.assert_array_equal(x.bias, y.bias)
    with h5py.File(tmp_path / "m.h5") as f:
        assert "optimizer_weights" not in f


def test_the_shipped_jamming_labels_are_the_distance_rule(tmp_path: Path) -> None:
    from hapticframe_raking import data_path, jamming_labels, write_jamming_labels

    write_jamming_labels("training", 40.0, tmp_path / "labels.npz")
    shipped = data_path("training").with_name("training-jamming-labels.npz")
    with np.load(tmp_path / "labels.npz") as fresh, np.load(shipped) as committed:
        np.testing.assert_array_equal(fresh["state"], committed["state"])
        np.testing.assert_array_equal(fresh["timestamps_s"], committed["timestamps_s"])
    trial = load_trials("training")[0]
    labels = jamming_labels(trial, 40.0)
    assert labels[0] == 0 and labels[-1] == 1
    assert np.all((trial.distance_mm <= 40.0) == (labels == 1))
