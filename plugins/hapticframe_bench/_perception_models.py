"""The six architectures of dissertation Tables 2.2-2.3, trained and scored on cached features.

An architecture is a stage of Figure 2.2 (``b``, ``c`` or ``d``, see
:mod:`._perception_data`) and a classifier:

- ``svm``: the ``linear-svm`` component (Platt-calibrated linear SVM, per frame);
- ``rnn``: for stages ``b`` and ``c`` the ``fusion-rnn`` component (one GRU stack per
  modality joined by a fully connected layer: the thesis's "RNN" for one modality and
  "F-RNN" for several); for stage ``d`` the ``sf-rnn`` component (SF-RNN).

The components are used through their public class API: inputs are handed over as the
channels the component reads (``<modality>_code`` for the recurrent ones, with the code
sizes set to the stage's sizes). When the coder emitted amplitudes (``amplitude="channel"``),
both stage-(d) models get them: the SF-RNN as ``<modality>_amplitude`` channels
(``amplitude_inputs``, narrowed to the plan's ``amplitude_modalities``), the SVM appended
to each modality's code (all of them). Recurrent models train on the training trials and
stop early on the validation trials, given to them explicitly. Scores are balanced
accuracies over all frames of a split (mean recall of "free" and "contact"), since about
four frames in five are free movement.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_sfrnn import (
    FusionRNNClassifier,
    FusionRNNConfig,
    LinearSVMClassifier,
    LinearSVMConfig,
    SFRNNClassifier,
    SFRNNConfig,
    balanced_accuracy,
    contact_figures,
)

from ._perception_data import PerceptionData, TrialFeatures, stage_amplitudes, stage_inputs

ALL_MODALITIES = ("pac", "pdc", "electrodes")

__all__ = [
    "Architecture",
    "TrainedModel",
    "predict_frames",
    "robustness_breakdown",
    "score",
    "step_time_ms",
    "train_architecture",
]


@dataclass(frozen=True)
class Architecture:
    """A stage of Figure 2.2 and a classifier, e.g. ``Architecture("d", "rnn")`` = SF-RNN."""

    stage: str
    classifier: str

    def __post_init__(self) -> None:
        if self.stage not in ("b", "c", "d") or self.classifier not in ("svm", "rnn"):
            raise ValueError(
                f"unknown architecture ({self.stage!r}, {self.classifier!r}); stage is 'b', 'c' "
                "or 'd' and classifier 'svm' or 'rnn'"
            )

    @property
    def label(self) -> str:
        if self.classifier == "svm":
            return f"({self.stage})+Linear SVM"
        return "(d)+RNN (SF-RNN)" if self.stage == "d" else f"({self.stage})+RNN"


@dataclass
class TrainedModel:
    """A fitted component with what it was built for."""

    architecture: Architecture
    modalities: tuple[str, ...]
    component: Any
    train_time_s: float
    training_metrics: dict[str, Any]
    #: Contact is decided when p(contact) exceeds this: 0.5 for the recurrent models (trained
    #: with class-balanced loss); the training contact rate for the SVM, whose Platt
    #: calibration restores the class frequencies (the balanced decision, which is what the
    #: thesis's oversampling of the contact class amounts to).
    contact_threshold: float = 0.5
    #: Modalities whose coder amplitude the stage-(d) model reads (None: all there are).
    amplitude_modalities: tuple[str, ...] | None = None


def _channel(arch: Architecture, modality: str) -> str:
    return f"{modality}_code" if arch.classifier == "rnn" else f"{modality}_{arch.stage}"


def _batch(
    trial: TrialFeatures, arch: Architecture, modalities: Sequence[str],
    amplitude_modalities: Sequence[str] | None = None,
) -> SampleBatch:
    inputs = stage_inputs(trial, arch.stage, modalities)
    amplitudes = stage_amplitudes(trial, modalities) if arch.stage == "d" else {}
    if amplitude_modalities is not None:
        amplitudes = {m: a for m, a in amplitudes.items() if m in amplitude_modalities}
    times = (1 + np.arange(len(trial), dtype=np.float64)) * 0.01
    if arch.classifier == "svm":
        # One flat vector per modality: the code, then its amplitude (if any).
        return SampleBatch(times, {
            _channel(arch, m): np.hstack([v, amplitudes[m]]) if m in amplitudes else v
            for m, v in inputs.items()
        })  # fmt: skip
    channels = {_channel(arch, m): v for m, v in inputs.items()}
    channels.update({f"{m}_amplitude": a for m, a in amplitudes.items()})
    return SampleBatch(times, channels)


def train_architecture(
    data: PerceptionData,
    arch: Architecture,
    modalities: Sequence[str],
    seed: int,
    rnn_settings: dict[str, Any],
    svm_settings: dict[str, Any] | None = None,
) -> TrainedModel:
    """Fit one architecture on the training trials (validation trials for early stopping).

    Every model is fitted on the cottonwood training trials only. The recurrent components
    get the validation trials as their explicit early-stopping set (``fit``'s
    ``validation_batches``); they used to get train + validation together and hold out a
    random validation-sized share themselves, which put part of the reported "validation"
    row in sample and gave the recurrent models more fitting data than the SVMs.
    """
    mods = tuple(m for m in ("pac", "pdc", "electrodes") if m in modalities)
    # Sizes from the data: the codes' sizes follow the coder's dictionaries.
    first = data.by_split("train")[0]
    width = {m: v.shape[1] for m, v in stage_inputs(first, arch.stage, ALL_MODALITIES).items()}
    amplitude_width = {m: v.shape[1] for m, v in stage_amplitudes(first, ALL_MODALITIES).items()}
    # ``amplitude_modalities`` (an SF-RNN setting) narrows the amplitudes the SF-RNN reads;
    # the stage-(d) SVM keeps every amplitude (without pac's it loses about 1.5 points on the
    # robustness set, and a baseline is never handicapped).
    chosen = rnn_settings.get("amplitude_modalities") if arch.classifier == "rnn" else None
    amp_mods = None if chosen is None else tuple(m for m in mods if m in chosen)
    if amp_mods is not None:
        amplitude_width = {m: w for m, w in amplitude_width.items() if m in amp_mods}
    with_amplitude = arch.stage == "d" and bool(amplitude_width)
    context = BuildContext(
        f"{arch.stage}-{arch.classifier}", np.random.default_rng(np.random.SeedSequence([seed, 3]))
    )
    if arch.classifier == "svm":
        config = LinearSVMConfig(
            inputs={
                _channel(arch, m): width[m] + (amplitude_width.get(m, 0) if with_amplitude else 0)
                for m in mods
            },
            **(svm_settings or {}),
        )
        component: Any = LinearSVMClassifier(config, context)
        trials = data.by_split("train")
    else:
        sizes = {f"{m}_code_size": width[m] for m in ALL_MODALITIES}
        trials = data.by_split("train")
        validation = data.by_split("validation")
        common = {"modalities": mods, **sizes, "progress": False,
                  "amplitude_inputs": with_amplitude, **rnn_settings,
                  "amplitude_modalities": amp_mods}
        # One settings dict serves both networks: each config takes the keys it knows
        # (gru_* for the SF-RNN, branch_* for the fusion RNN).
        cls, config_cls = ((SFRNNClassifier, SFRNNConfig) if arch.stage == "d"
                           else (FusionRNNClassifier, FusionRNNConfig))
        known = {k: v for k, v in common.items() if k in config_cls.model_fields}
        component = cls(config_cls(**known), context)
    batches = [_batch(t, arch, mods, amp_mods) for t in trials]
    started = time.perf_counter()
    if arch.classifier == "svm":
        component.fit(batches, [t.labels for t in trials])
    else:
        # Without validation trials the component holds out validation_fraction itself.
        val_batches = [_batch(t, arch, mods, amp_mods) for t in validation]
        component.fit(batches, [t.labels for t in trials], val_batches or None,
                      [t.labels for t in validation] if validation else None)
    elapsed = time.perf_counter() - started
    metrics = _training_report(component)
    threshold = 0.5
    if arch.classifier == "svm":
        threshold = float(np.mean(np.concatenate([t.labels for t in trials])))
    return TrainedModel(arch, mods, component, elapsed, metrics, threshold, amp_mods)


def _training_report(component: Any) -> dict[str, Any]:
    """What a fitted component reports of its training (epochs, losses, trials), or {}.

    Read from ``training_report`` (a method or a mapping), else from the older
    ``training_metrics`` attribute.
    """
    report = getattr(component, "training_report", None)
    if callable(report):
        report = report()
    if report is None:
        report = getattr(component, "training_metrics", None)
    return dict(report or {})


def predict_frames(
    model: TrainedModel, trial: TrialFeatures, present: Sequence[str] | None = None
) -> np.ndarray:
    """The predicted state of each frame of ``trial`` (0 free, 1 contact).

    ``present`` names the modalities handed to the model (default: all it was trained
    on); the others are absent and zero-filled by the component (Table A.1).
    """
    present = model.modalities if present is None else present
    batch = _batch(trial, model.architecture, [m for m in model.modalities if m in present],
                   model.amplitude_modalities)
    with warnings.catch_warnings():
        # A modality left out on purpose (Table A.1) is zero-filled; no warning wanted.
        warnings.simplefilter("ignore", UserWarning)
        # Recurrent models score a trial in one sequence call (same as streaming up to
        # float32 rounding); step_time_ms times the streaming path.
        predict = getattr(model.component, "predict_sequence", model.component.predict_proba)
        proba = predict(batch)
    contact = np.asarray(proba.probabilities, dtype=np.float64)[:, 1]
    return (contact > model.contact_threshold).astype(np.int64)


def score(
    model: TrainedModel,
    trials: Sequence[TrialFeatures],
    present: Sequence[str] | None = None,
) -> dict[str, float]:
    """Balanced and plain accuracy over the frames of ``trials``.

    ``present`` names the modalities handed to the model (default: all it was trained
    on); the others are absent and zero-filled by the component (Table A.1).
    """
    use = tuple(model.modalities if present is None else present)
    truth, predicted = [], []
    for trial in trials:
        truth.append(trial.labels)
        predicted.append(predict_frames(model, trial, use))
    y, p = np.concatenate(truth), np.concatenate(predicted)
    return {"balanced_accuracy": balanced_accuracy(y, p), "accuracy": float(np.mean(y == p)),
            "frames": float(y.size)}


def robustness_breakdown(
    trials: Sequence[TrialFeatures], predicted: Sequence[np.ndarray]
) -> dict[str, dict[str, Any]]:
    """:func:`hapticframe_sfrnn.contact_figures` of scored trials grouped by their conditions.

    Keys: ``orientation_deg`` and ``object_offset_m`` (each condition's value as a string,
    over every medium), and ``medium_orientation_deg`` (per medium, then per orientation):
    Table 2.4 read by the conditions the thesis varied (§2.6.3), so that a loss can be
    traced to the fingertip's pose or the object's place rather than to the medium.
    """
    if len(trials) != len(predicted):
        raise ValueError(f"{len(trials)} trials but {len(predicted)} predictions")

    def figures(chosen: list[int]) -> dict[str, Any]:
        return contact_figures([trials[i].labels for i in chosen], [predicted[i] for i in chosen])

    def groups(key: Any, among: Sequence[int]) -> dict[str, list[int]]:
        out: dict[str, list[int]] = {}
        for i in among:
            out.setdefault(f"{key(trials[i]):g}", []).append(i)
        return dict(sorted(out.items(), key=lambda kv: float(kv[0])))

    every = range(len(trials))
    media: dict[str, list[int]] = {}
    for i in every:
        media.setdefault(trials[i].medium, []).append(i)
    return {
        "orientation_deg": {k: figures(v) for k, v in
                            groups(lambda t: t.orientation_deg, every).items()},
        "object_offset_m": {k: figures(v) for k, v in
                            groups(lambda t: t.object_offset_m, every).items()},
        "medium_orientation_deg": {
            medium: {k: figures(v) for k, v in
                     groups(lambda t: t.orientation_deg, chosen).items()}
            for medium, chosen in media.items()
        },
    }


def step_time_ms(model: TrainedModel, trial: TrialFeatures, frames: int = 200) -> float:
    """Median time of one streaming step (one frame in, probabilities out), one thread."""
    import torch
    from threadpoolctl import threadpool_limits

    batch = _batch(trial, model.architecture, model.modalities, model.amplitude_modalities)
    n = min(frames, len(batch))
    times = np.empty(n)
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            model.component.reset()
            for i in range(n):
                frame = batch.select(slice(i, i + 1))
                start = time.perf_counter()
                model.component.update(frame)
                times[i] = time.perf_counter() - start
    finally:
        torch.set_num_threads(previous)
        model.component.reset()
    return 1e3 * float(np.median(times))
