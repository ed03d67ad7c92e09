"""Training, streaming, artifacts and missing modalities of sf-rnn, fusion-rnn and linear-svm.

The end-to-end runs train on synthetic BioTac trials (``hapticframe_biotac.generate_trial``)
turned into *code-like* features directly, not through ``emd-features`` + ``sparse-coding``
(that chain costs about 1-2 s per 300-frame trial here, too slow for a unit test): per
frame, ``pac_code`` is the 22 pac samples minus their mean, ``pdc_code`` the pdc minus the
trial's resting value and ``electrodes_code`` the 19 electrodes minus theirs, so every
"code" is zero at rest like a sparse code. The classifiers are scored on held-out trials
from a fresh state: the recurrent ones in one sequence call (``predict_sequence``), which
the streaming tests check against per-frame steps (``predict_proba``, ``update``).
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, RunOutcome, SampleBatch

torch = pytest.importorskip("torch")
pytest.importorskip("sklearn")

from hapticframe_biotac import TrialSpec, generate_trial  # noqa: E402
from hapticframe_sfrnn._config import (  # noqa: E402
    FusionRNNConfig,
    LinearSVMConfig,
    SFRNNConfig,
)
from hapticframe_sfrnn._functional import balanced_accuracy  # noqa: E402
from hapticframe_sfrnn._linear_svm import LinearSVMClassifier  # noqa: E402
from hapticframe_sfrnn._recurrent import FusionRNNClassifier, SFRNNClassifier  # noqa: E402

SIZES = {"pac_code_size": 22, "pdc_code_size": 1, "electrodes_code_size": 19}
SVM_INPUTS = {"pac_code": 22, "pdc_code": 1, "electrodes_code": 19}
Labelled = list[tuple[SampleBatch, np.ndarray]]


def code_like(trial: object) -> tuple[SampleBatch, np.ndarray]:
    electrodes = trial.electrodes  # type: ignore[attr-defined]
    pdc = trial.pdc  # type: ignore[attr-defined]
    pac = trial.pac  # type: ignore[attr-defined]
    channels = {
        "pac_code": pac - pac.mean(axis=1, keepdims=True),
        "pdc_code": (pdc - np.median(pdc[:10]))[:, None],
        "electrodes_code": electrodes - np.median(electrodes[:10], axis=0),
    }
    labels = trial.contact.astype(int)  # type: ignore[attr-defined]
    return SampleBatch(trial.timestamps_s, channels), labels  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def trials() -> tuple[Labelled, Labelled]:
    """30 cottonwood trials at 4 cm/s, a third with the object: 22 to train, 8 held out."""
    rng = np.random.default_rng(5)
    specs = [TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, i % 3 == 0) for i in range(30)]
    data = [code_like(generate_trial(spec, rng)) for spec in specs]
    return data[:22], data[22:]


def context(seed: int = 0, name: str = "clf") -> BuildContext:
    return BuildContext(name, np.random.default_rng(seed))


def held_out_score(classifier: object, test: Labelled) -> float:
    # The recurrent networks score whole recordings in one call (predict_sequence, equal to
    # the frame-by-frame stream up to float32 rounding, checked in test_sfrnn_amplitude.py);
    # stepping frame by frame is what the streaming tests here are for, and is ~50x slower.
    sequence = getattr(classifier, "predict_sequence", None)
    if sequence is not None:
        predicted = np.concatenate([sequence(b).labels for b, _ in test])
    else:
        predict = classifier.predict  # type: ignore[attr-defined]
        predicted = np.concatenate([predict(b) for b, _ in test])
    truth = np.concatenate([y for _, y in test])
    return balanced_accuracy(truth, predicted)


@pytest.fixture(scope="module")
def sfrnn(trials: tuple[Labelled, Labelled]) -> SFRNNClassifier:
    """The thesis's architecture (fusion → 4 × 50 GRU, dropout 0.4), trained briefly: two
    epochs reach 0.98 held-out balanced accuracy on these trials (the untrained net: 0.73)."""
    train, _ = trials
    clf = SFRNNClassifier(SFRNNConfig(**SIZES, max_epochs=2, progress=False), context(0))
    clf.fit([b for b, _ in train], [y for _, y in train])
    return clf


def test_sfrnn_beats_chance_on_held_out_trials(
    sfrnn: SFRNNClassifier, trials: tuple[Labelled, Labelled]
) -> None:
    _, test = trials
    assert sfrnn.fitted
    metrics = sfrnn.training_metrics
    assert 1 <= metrics["best_epoch"] <= metrics["epochs"] <= 2
    assert metrics["validation_trials"] >= 2 and metrics["train_windows"] > 100
    assert np.isfinite(metrics["validation_loss"])
    assert held_out_score(sfrnn, test) >= 0.8


def test_training_improves_on_the_untrained_network(
    sfrnn: SFRNNClassifier, trials: tuple[Labelled, Labelled]
) -> None:
    # The score must come from training, not from how separable the features are alone.
    _, test = trials
    untrained = SFRNNClassifier(SFRNNConfig(**SIZES, progress=False), context(0))
    assert not untrained.fitted
    assert held_out_score(sfrnn, test) >= held_out_score(untrained, test) + 0.1


def test_streaming_in_chunks_equals_the_batch_path(
    sfrnn: SFRNNClassifier, trials: tuple[Labelled, Labelled]
) -> None:
    batch, _ = trials[1][0]
    whole = sfrnn.predict_proba(batch)
    assert whole.probabilities.dtype == np.float64
    assert np.array_equal(whole.timestamps_s, batch.timestamps_s)
    sfrnn.reset()
    sizes = np.random.default_rng(1).integers(1, 40, size=len(batch))
    rows, start = [], 0
    for size in sizes:
        if start >= len(batch):
            break
        rows.append(sfrnn.update(batch.select(slice(start, start + int(size)))).probabilities)
        start += int(size)
    streamed = np.vstack(rows)
    assert streamed.shape == whole.probabilities.shape
    assert np.max(np.abs(streamed - whole.probabilities)) <= 1e-6
    # The one-call path that scores held-out trials computes the same, up to float32 rounding.
    sequence = sfrnn.predict_sequence(batch).probabilities
    assert np.max(np.abs(sequence - whole.probabilities)) <= 1e-5
    # The hidden state carries over: the same frames from a fresh state differ.
    sfrnn.reset()
    tail = sfrnn.update(batch.select(slice(100, None))).probabilities
    assert np.max(np.abs(tail - whole.probabilities[100:])) > 1e-6


def test_save_and_load_give_identical_probabilities(
    sfrnn: SFRNNClassifier, trials: tuple[Labelled, Labelled], tmp_path: Path
) -> None:
    batch, _ = trials[1][1]
    expected = sfrnn.predict_proba(batch).probabilities
    sfrnn.save(tmp_path / "model")
    assert sorted(p.name for p in (tmp_path / "model").iterdir()) == ["model.json", "weights.pt"]
    meta = json.loads((tmp_path / "model" / "model.json").read_text())
    assert meta["architecture"] == "sf-rnn" and meta["classes"] == ["free", "contact"]
    assert meta["modalities"] == ["pac", "pdc", "electrodes"] and meta["fitted"]
    assert meta["versions"]["torch"] == torch.__version__
    assert meta["training_metrics"]["epochs"] >= 1
    # Tensors only: loadable with weights_only=True.
    state = torch.load(tmp_path / "model" / "weights.pt", weights_only=True)
    assert "input_scale" in state
    # A default-configured component adopts the saved (smaller) architecture at build time.
    loaded = SFRNNClassifier(SFRNNConfig(model_dir=str(tmp_path / "model")), context(99))
    assert loaded.fitted and loaded.config.pac_code_size == 22
    assert np.array_equal(loaded.predict_proba(batch).probabilities, expected)
    with pytest.raises(ValueError, match="sf-rnn"):
        FusionRNNClassifier(FusionRNNConfig(model_dir=str(tmp_path / "model")), context(0))
    with pytest.raises(ValueError, match="lacks"):
        SFRNNClassifier(SFRNNConfig(model_dir=str(tmp_path)), context(0))


def test_missing_modality_is_zero_filled_and_reported(
    sfrnn: SFRNNClassifier, trials: tuple[Labelled, Labelled], tmp_path: Path
) -> None:
    batch = trials[1][0][0].select(slice(0, 100))  # one second steps through quickly
    without = SampleBatch(
        batch.timestamps_s, {k: v for k, v in batch.channels.items() if k != "electrodes_code"}
    )
    zeroed = SampleBatch(
        batch.timestamps_s,
        {**batch.channels, "electrodes_code": np.zeros_like(batch.channels["electrodes_code"])},
    )
    flagged = SampleBatch(
        batch.timestamps_s, dict(batch.channels), {"electrodes_code": np.zeros(len(batch), bool)}
    )
    sfrnn.fill_report.absent_frames.clear()
    sfrnn.fill_report.invalid_frames.clear()
    sfrnn._warned.clear()
    with pytest.warns(UserWarning, match="electrodes_code"):
        absent = sfrnn.predict_proba(without).probabilities
    assert np.isfinite(absent).all()
    assert np.array_equal(absent, sfrnn.predict_proba(zeroed).probabilities)
    assert np.array_equal(absent, sfrnn.predict_proba(flagged).probabilities)
    assert not np.array_equal(absent, sfrnn.predict_proba(batch).probabilities)
    assert sfrnn.fill_report.absent_frames["electrodes_code"] == len(batch)
    assert sfrnn.fill_report.invalid_frames["electrodes_code"] == len(batch)
    outcome = RunOutcome(tmp_path, None, (), {}, 0.0, figures=False)
    metrics = sfrnn.finalize(outcome)
    assert metrics["clf_electrodes_code_absent_frames"] == len(batch)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once per channel only
        sfrnn.predict_proba(without)


def test_training_on_a_subset_of_modalities(trials: tuple[Labelled, Labelled]) -> None:
    train, test = trials
    config = SFRNNConfig(
        **SIZES, modalities=("electrodes",), gru_layers=2, gru_units=16, max_epochs=4,
        progress=False,
    )
    clf = SFRNNClassifier(config, context(3))
    assert clf.groups == {"electrodes_code": 19}
    clf.fit([b for b, _ in train[:12]], [y for _, y in train[:12]])
    assert held_out_score(clf, test) >= 0.7


def test_fusion_rnn_trains_and_streams(trials: tuple[Labelled, Labelled], tmp_path: Path) -> None:
    train, test = trials
    config = FusionRNNConfig(
        **SIZES, branch_layers=1, branch_units=16, fusion_units=16, max_epochs=3, progress=False
    )
    clf = FusionRNNClassifier(config, context(4))
    clf.fit([b for b, _ in train[:12]], [y for _, y in train[:12]])
    assert held_out_score(clf, test) >= 0.7
    batch = test[0][0]
    whole = clf.predict_proba(batch).probabilities
    clf.reset()
    parts = [
        clf.update(batch.select(slice(s, s + 17))).probabilities
        for s in range(0, len(batch), 17)
    ]
    assert np.max(np.abs(np.vstack(parts) - whole)) <= 1e-6
    clf.save(tmp_path / "fusion")
    again = FusionRNNClassifier(FusionRNNConfig(model_dir=str(tmp_path / "fusion")), context(8))
    assert np.array_equal(again.predict_proba(batch).probabilities, whole)


def test_fit_is_deterministic_for_a_seed(trials: tuple[Labelled, Labelled]) -> None:
    train, test = trials
    config = SFRNNConfig(
        **SIZES, gru_layers=1, gru_units=8, fusion_units=8, max_epochs=2, progress=False
    )
    runs = []
    for _ in range(2):
        clf = SFRNNClassifier(config, context(7))
        clf.fit([b for b, _ in train[:8]], [y for _, y in train[:8]])
        runs.append(clf.predict_proba(test[0][0]).probabilities)
    assert np.array_equal(runs[0], runs[1])
    clf.fit([b for b, _ in train[:8]], [y for _, y in train[:8]])  # a refit starts afresh
    assert np.array_equal(clf.predict_proba(test[0][0]).probabilities, runs[1])
    other = SFRNNClassifier(config, context(8))
    other.fit([b for b, _ in train[:8]], [y for _, y in train[:8]])
    assert not np.array_equal(other.predict_proba(test[0][0]).probabilities, runs[0])


def test_fit_rejects_bad_training_data(trials: tuple[Labelled, Labelled]) -> None:
    batch, labels = trials[0][0]
    config = SFRNNConfig(**SIZES, gru_layers=1, gru_units=4, progress=False)
    clf = SFRNNClassifier(config, context())
    with pytest.raises(ValueError, match="label arrays"):
        clf.fit([batch], [])
    with pytest.raises(ValueError, match="one per frame"):
        clf.fit([batch], [labels[:-1]])
    with pytest.raises(ValueError, match="integers"):
        clf.fit([batch], [labels + 1])
    wrong = SampleBatch(
        batch.timestamps_s, {**batch.channels, "pac_code": np.zeros((len(batch), 5))}
    )
    with pytest.raises(ValueError, match="values per frame"):
        clf.fit([wrong], [labels])


def test_linear_svm_on_code_like_features(
    trials: tuple[Labelled, Labelled], tmp_path: Path
) -> None:
    train, test = trials
    svm = LinearSVMClassifier(LinearSVMConfig(inputs=SVM_INPUTS), context(5))
    svm.fit([b for b, _ in train], [y for _, y in train])
    assert svm.fitted and svm.training_metrics["train_frames"] > 1000
    assert held_out_score(svm, test) >= 0.7
    batch = test[0][0]
    probs = svm.predict_proba(batch).probabilities
    assert probs.dtype == np.float64 and np.allclose(probs.sum(axis=1), 1.0)
    svm.save(tmp_path / "svm")
    assert sorted(p.name for p in (tmp_path / "svm").iterdir()) == ["model.json", "model.npz"]
    loaded = LinearSVMClassifier(LinearSVMConfig(model_dir=str(tmp_path / "svm")), context(1))
    assert loaded.groups == SVM_INPUTS
    assert np.array_equal(loaded.predict_proba(batch).probabilities, probs)
    without = SampleBatch(batch.timestamps_s, {"pac_code": batch.channels["pac_code"]})
    assert np.isfinite(loaded.predict_proba(without).probabilities).all()
    assert loaded.fill_report.absent_frames["electrodes_code"] == len(batch)


def test_linear_svm_on_raw_frames_and_bad_input(trials: tuple[Labelled, Labelled]) -> None:
    rng = np.random.default_rng(2)
    raw = []
    for i in range(6):
        trial = generate_trial(TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, i % 2 == 0), rng)
        channels = {"pac": trial.pac, "pdc": trial.pdc, "electrodes": trial.electrodes}
        raw.append((SampleBatch(trial.timestamps_s, channels), trial.contact.astype(int)))
    svm = LinearSVMClassifier(
        LinearSVMConfig(inputs={"pac": 22, "pdc": 1, "electrodes": 19}), context(6)
    )
    svm.fit([b for b, _ in raw], [y for _, y in raw])
    probs = svm.predict_proba(raw[0][0]).probabilities
    assert probs.shape == (len(raw[0][0]), 2) and np.isfinite(probs).all()
    with pytest.raises(ValueError, match="one class"):
        svm.fit([raw[1][0]], [np.zeros(len(raw[1][0]), dtype=int)])


def test_linear_svm_counts_convergence_warnings_instead_of_printing_them(
    trials: tuple[Labelled, Labelled], recwarn: pytest.WarningsRecorder
) -> None:
    train, _ = trials
    svm = LinearSVMClassifier(LinearSVMConfig(inputs=SVM_INPUTS, max_iter=1), context(5))
    svm.fit([b for b, _ in train[:6]], [y for _, y in train[:6]])
    assert svm.training_metrics["convergence_warnings"] >= 1  # one iteration cannot converge
    assert not [w for w in recwarn if "converge" in str(w.message)]


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_sfrnn_reads_what_the_feature_chain_emits() -> None:
    """Wiring through the real emd-features + sparse-coding chain (no accuracy claim).

    Four short trials, pdc and electrodes only and small dictionaries keep it quick; the
    classifier is sized from the coder's output channels and stores the extractors'
    settings (delay included) with its model.
    """
    from hapticframe_tactile_features._config import EMDFeaturesConfig, SparseCodingConfig
    from hapticframe_tactile_features._emd_features import EMDFeatureExtractor
    from hapticframe_tactile_features._sparse_coding import SparseCodingExtractor

    modalities = ("pdc", "electrodes")
    fx = EMDFeatureExtractor(
        EMDFeaturesConfig(modalities=modalities, delay_frames=2, max_sifts=10), context(0, "fx")
    )
    coder = SparseCodingExtractor(
        SparseCodingConfig(modalities=modalities, pdc_atoms=12, electrodes_atoms=16, fit_epochs=1),
        context(1, "codes"),
    )
    rng = np.random.default_rng(9)
    features, labels = [], []
    for i in range(4):
        trial = generate_trial(TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, i % 2 == 0), rng)
        frames = SampleBatch(
            trial.timestamps_s[:100], {"pdc": trial.pdc[:100], "electrodes": trial.electrodes[:100]}
        )
        fx.reset()
        tensors = fx.update(frames)
        # Features carry the times of the frames they describe: label them by time.
        index = np.searchsorted(trial.timestamps_s, tensors.timestamps_s)
        features.append(tensors)
        labels.append(trial.contact[index].astype(int))
    coder.fit(features)
    codes = [coder.update(f) for f in features]
    sizes = {f"{m}_code_size": coder.n_atoms(m) for m in modalities}
    inputs = {"fx": fx, "codes": coder}
    clf = SFRNNClassifier(
        SFRNNConfig(
            modalities=modalities, **sizes, gru_layers=1, gru_units=8, fusion_units=8,
            max_epochs=2, progress=False,
        ),
        BuildContext("sf", np.random.default_rng(2), inputs),
    )
    assert set(clf.groups) == set(codes[0].channels)
    clf.fit(codes, labels)
    out = clf.predict_proba(codes[0])
    assert np.array_equal(out.timestamps_s, codes[0].timestamps_s)
    assert np.isfinite(out.probabilities).all()
    assert clf.feature_settings["fx"]["delay_s"] == pytest.approx(0.02)
    assert clf.metadata()["feature_settings"]["fx"]["extractor"] == "emd-features"


@pytest.mark.parametrize("network", ["sf", "fusion"])
def test_sequence_forward_equals_per_frame_steps(network: str) -> None:
    # Training runs whole windows, streaming runs one frame at a time: the same recurrence.
    from hapticframe_sfrnn._networks import FusionRNNNet, SFRNNNet, init_parameters

    net = SFRNNNet([5, 3], 6, 3, 7, 0.4) if network == "sf" else FusionRNNNet([5, 3], 2, 4, 6, 0.4)
    init_parameters(net, torch.Generator().manual_seed(0))
    net.eval()
    x = torch.randn(2, 30, 8, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        whole, final = net(x, net.initial_state(2))
        state, steps = net.initial_state(2), []
        for t in range(30):
            out, state = net(x[:, t : t + 1], state)
            steps.append(out)
    assert torch.allclose(torch.cat(steps, dim=1), whole, atol=1e-5)
    assert all(torch.allclose(a, b, atol=1e-5) for a, b in zip(state, final, strict=True))


def test_modality_dropout_zeroes_whole_modalities_but_never_all() -> None:
    from hapticframe_sfrnn._training import _modality_mask

    x = torch.ones(400, 5, 4)
    masked = _modality_mask(x, [3, 1], 0.5, torch.Generator().manual_seed(0))
    first, second = masked[:, :, :3], masked[:, :, 3:]
    # Each modality is all kept or all dropped per window, and never both dropped.
    assert torch.all((first == 0).all(dim=(1, 2)) | (first == 1).all(dim=(1, 2)))
    dropped = torch.stack([(first == 0).all(dim=(1, 2)), (second == 0).all(dim=(1, 2))], dim=1)
    assert not dropped.all(dim=1).any()
    assert 0.2 < dropped.float().mean() < 0.5
    assert torch.equal(_modality_mask(x, [3, 1], 0.0, torch.Generator()), x)


def test_training_reports_progress(
    trials: tuple[Labelled, Labelled], capsys: pytest.CaptureFixture[str]
) -> None:
    train, _ = trials
    config = SFRNNConfig(
        **SIZES, gru_layers=1, gru_units=4, fusion_units=4, max_epochs=2, modality_dropout=0.3,
        progress=True,
    )
    clf = SFRNNClassifier(config, context(1))
    clf.fit([b for b, _ in train[:6]], [y for _, y in train[:6]])
    err = capsys.readouterr().err
    # stderr is not a terminal here (as in a log or a pipe): a plain line per epoch, no bar.
    assert "epoch 1: train loss" in err and "epoch 2: train loss" in err, err
    assert "\r" not in err
    assert clf.training_metrics["epochs"] == 2


def test_explicit_validation_trials_are_the_early_stopping_set(
    trials: tuple[Labelled, Labelled],
) -> None:
    train, held_out = trials
    fit_on, val = train[:12], held_out[:4]
    config = SFRNNConfig(
        **SIZES, gru_layers=1, gru_units=8, fusion_units=8, max_epochs=2, progress=False
    )
    clf = SFRNNClassifier(config, context(3))
    # Validation inputs 100x larger: the input scale must come from the training trials only.
    big_val = [SampleBatch(b.timestamps_s, {k: 100.0 * v for k, v in b.channels.items()})
               for b, _ in val]  # fmt: skip
    clf.fit([b for b, _ in fit_on], [y for _, y in fit_on], big_val, [y for _, y in val])
    metrics = clf.training_metrics
    assert metrics["validation_source"] == "given"
    assert metrics["train_trials"] == 12 and metrics["validation_trials"] == 4
    reference = SFRNNClassifier(config, context(3))
    reference.fit([b for b, _ in fit_on], [y for _, y in fit_on])  # random hold-out instead
    assert reference.training_metrics["validation_source"] == "held_out"
    assert reference.training_metrics["train_trials"] < 12
    np.testing.assert_array_equal(clf.net.input_scale.numpy(), reference.net.input_scale.numpy())
    # The windows trained on are those of all 12 trials, none of the validation trials'.
    assert metrics["train_windows"] > reference.training_metrics["train_windows"]
    with pytest.raises(ValueError, match="together"):
        clf.fit([b for b, _ in fit_on], [y for _, y in fit_on], big_val)
    with pytest.raises(ValueError, match="label arrays"):
        clf.fit([b for b, _ in fit_on], [y for _, y in fit_on], big_val, [val[0][1]])


def test_train_device_names_are_checked() -> None:
    assert SFRNNConfig(**SIZES, train_device="cuda:1").train_device == "cuda:1"
    for bad in ("gpu", "cuda:", "CUDA", "cuda:x", ""):
        with pytest.raises(ValueError, match="train_device"):
            SFRNNConfig(**SIZES, train_device=bad)


@pytest.mark.skipif(torch.cuda.is_available(), reason="this machine has a CUDA device")
def test_training_on_cuda_without_one_is_a_clear_error(trials: tuple[Labelled, Labelled]) -> None:
    train, _ = trials
    config = SFRNNConfig(**SIZES, gru_layers=1, gru_units=4, max_epochs=1, progress=False,
                         train_device="cuda")
    clf = SFRNNClassifier(config, context())
    with pytest.raises(ValueError, match="no CUDA device"):
        clf.fit([b for b, _ in train[:4]], [y for _, y in train[:4]])
    assert not clf.fitted
    assert next(clf.net.parameters()).device.type == "cpu"


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("network", ["sf", "fusion"])
def test_training_on_cuda_follows_the_cpu_run(
    network: str, trials: tuple[Labelled, Labelled]
) -> None:
    """Same masks and window order on either device; the weights differ by rounding only."""
    train, test = trials
    cls, config_cls = ((SFRNNClassifier, SFRNNConfig) if network == "sf"
                       else (FusionRNNClassifier, FusionRNNConfig))
    fitted = {}
    for device in ("cpu", "cuda"):
        config = config_cls(**SIZES, max_epochs=1, progress=False, train_device=device,
                            modality_dropout=0.3)
        clf = cls(config, context(3))
        clf.fit([b for b, _ in train[:8]], [y for _, y in train[:8]])
        assert clf.training_metrics["train_device"].startswith(device)
        assert next(clf.net.parameters()).device.type == "cpu"  # streams on the CPU
        fitted[device] = clf
    # Rounding (cuDNN against the CPU kernels) moves the weights a tiny fraction of what the
    # epoch moved them; other dropout masks or window order move them about half as far
    # again (0.57 of the movement, measured on the CPU with the next fit seed).
    from hapticframe_sfrnn._networks import init_parameters

    start = cls(config_cls(**SIZES), context(3))
    init_parameters(start.net, torch.Generator().manual_seed(start._init_seed))

    def flat(clf: object) -> torch.Tensor:
        state = clf.net.state_dict()  # type: ignore[attr-defined]
        return torch.cat([v.flatten() for k, v in state.items() if k != "input_scale"])

    moved = (flat(fitted["cpu"]) - flat(start)).norm()
    assert moved > 0
    assert (flat(fitted["cpu"]) - flat(fitted["cuda"])).norm() < 0.1 * moved
    p_cpu = fitted["cpu"].predict_proba(test[0][0]).probabilities
    p_gpu = fitted["cuda"].predict_proba(test[0][0]).probabilities
    assert np.abs(p_cpu - p_gpu).max() < 0.05


def test_a_quiet_run_silences_the_training_progress(
    trials: tuple[Labelled, Labelled], capsys: pytest.CaptureFixture[str]
) -> None:
    # The component's own setting asks for progress; the run's (``--quiet``) overrides it.
    train, _ = trials
    config = SFRNNConfig(**SIZES, gru_layers=1, gru_units=4, fusion_units=4, max_epochs=2,
                         progress=True)
    for progress in (True, False):
        clf = SFRNNClassifier(config, BuildContext("clf", np.random.default_rng(0),
                                                   progress=progress))
        capsys.readouterr()
        clf.fit([b for b, _ in train[:6]], [y for _, y in train[:6]])
        drawn = capsys.readouterr().err
        assert clf.fitted and clf.config.progress
        assert bool(drawn.strip()) is progress, drawn
