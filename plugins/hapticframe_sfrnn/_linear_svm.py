"""The ``linear-svm`` classifier: a per-frame linear SVM with Platt-calibrated probabilities.

The thesis's linear baselines (§2.7) on stage (b) IMFs, (c) feature tensors or (d) sparse
codes: the configured channels are flattened and concatenated per frame, standardised with
the training frames' mean and spread, and scored by ``w · x + b``. Probabilities are
``P(contact) = 1 / (1 + exp(A f + B))`` (Platt scaling), the calibrator of
``CalibratedClassifierCV(LinearSVC(), method="sigmoid", ensemble=False)`` fitted on folds
grouped by trial. The contact class is balanced by ``class_weight="balanced"`` in place of
the thesis's random oversampling (the same expected loss, without duplicated rows).

Inference is numpy only: the fitted coefficients, intercept, standardisation and Platt
parameters are copied out of scikit-learn, saved as ``model.npz`` (``allow_pickle=False``)
plus ``model.json``, and evaluated here; scikit-learn is imported only inside :meth:`fit`.
Frames are independent, so streaming equals batch trivially. Missing, flagged or non-finite
channels are zero-filled after standardisation (the training mean) and counted.

Before :meth:`fit` (and without ``model_dir``) the weights are Gaussian draws from
``context.rng`` with unit Platt slope: deterministic, runnable, meaningless.
"""

from __future__ import annotations

import json
import platform
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from pydantic import ValidationError

from hapticframe import atomic_write, save_npz
from hapticframe.artifacts import read_json_object, read_npz_arrays, schema_error
from hapticframe.kinds import BuildContext, Classifier, ClassProbabilities, RunOutcome, SampleBatch

from ._config import CLASSES, LinearSVMConfig
from ._functional import (
    INPUT_CLIP,
    FillReport,
    assemble_inputs,
    balanced_accuracy,
    check_labels,
    sigmoid_pair,
    version_of,
)
from ._persist import MAX_SVM_WIDTH, SVMModelFile, validate_config

__all__ = ["SVM_FORMAT", "LinearSVMClassifier"]

SVM_FORMAT = "hapticframe-linear-svm"
_FORMAT_VERSION = 1


class LinearSVMClassifier(Classifier):
    """Linear SVM on flattened per-frame channels, Platt-calibrated (free / contact)."""

    def __init__(self, config: LinearSVMConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.groups: dict[str, int] = {k: int(v) for k, v in config.inputs.items()}
        width = sum(self.groups.values())
        self.coef = context.rng.standard_normal(width) / np.sqrt(width)
        self.intercept = 0.0
        self.mean = np.zeros(width)
        self.spread = np.ones(width)
        # Platt parameters: P(contact) = expit(-(A f + B)).
        self.platt_a, self.platt_b = -1.0, 0.0
        self._seed = int(context.rng.integers(2**31 - 1))
        self.fitted = False
        self.training_metrics: dict[str, Any] = {}
        self.fill_report = FillReport()
        if config.model_dir is not None:
            self.load(config.model_dir)

    @property
    def classes(self) -> tuple[str, ...]:
        return CLASSES

    def _features(self, batch: SampleBatch, report: FillReport | None) -> np.ndarray:
        x, present = assemble_inputs(batch, self.groups, report)
        z = (x - self.mean) / self.spread
        col = 0
        for j, size in enumerate(self.groups.values()):
            z[~present[:, j], col : col + size] = 0.0  # missing → the training mean
            col += size
        return np.clip(z, -INPUT_CLIP, INPUT_CLIP)

    def decision_function(self, batch: SampleBatch) -> np.ndarray:
        """SVM score ``w · z + b`` per frame (positive towards contact)."""
        return self._features(batch, self.fill_report) @ self.coef + self.intercept

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        score = self.decision_function(batch)
        probs = sigmoid_pair(-(self.platt_a * score + self.platt_b))
        return ClassProbabilities(batch.timestamps_s, probs, CLASSES)

    def fit(self, batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> None:
        """Fit the SVM and its Platt calibration on labelled trials (one batch per trial).

        Raises
        ------
        ValueError
            On mismatched lengths, labels outside {0, 1}, or a single class.
        """
        from sklearn.calibration import CalibratedClassifierCV
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.svm import LinearSVC

        if len(batches) != len(labels):
            raise ValueError(f"{len(batches)} batches but {len(labels)} label arrays")
        started = time.perf_counter()
        xs, ys, groups = [], [], []
        for i, (batch, y) in enumerate(zip(batches, labels, strict=True)):
            x, _ = assemble_inputs(batch, self.groups)
            xs.append(x)
            ys.append(check_labels(y, len(batch), len(CLASSES)))
            groups.append(np.full(len(batch), i))
        x, y, g = np.vstack(xs), np.concatenate(ys), np.concatenate(groups)
        if np.unique(y).size < 2:
            raise ValueError("the training frames hold only one class")
        self.mean = x.mean(axis=0)
        spread = x.std(axis=0)
        self.spread = np.where(spread > 1e-12 * np.maximum(np.abs(self.mean), 1.0), spread, 1.0)
        z = (x - self.mean) / self.spread
        splits = self._calibration_splits([bool(y_i.any()) for y_i in ys], g)
        svm = LinearSVC(
            C=self.config.c,
            class_weight="balanced" if self.config.balance_classes else None,
            max_iter=self.config.max_iter,
            random_state=self._seed,
        )
        model = CalibratedClassifierCV(svm, method="sigmoid", cv=splits, ensemble=False)
        # liblinear warns once per fold and fit when it stops at max_iter: counted in the
        # training metrics instead of printed (a benchmark fits dozens of these).
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            model.fit(z, y)
        unconverged = 0
        for warning in caught:
            if issubclass(warning.category, ConvergenceWarning):
                unconverged += 1
            else:
                warnings.warn_explicit(warning.message, warning.category, warning.filename,
                                       warning.lineno)
        calibrated = model.calibrated_classifiers_[0]
        self.coef = np.asarray(calibrated.estimator.coef_, dtype=np.float64).ravel().copy()
        self.intercept = float(np.ravel(calibrated.estimator.intercept_)[0])
        self.platt_a = float(calibrated.calibrators[0].a_)
        self.platt_b = float(calibrated.calibrators[0].b_)
        self.fitted = True
        train_pred = np.argmax(
            sigmoid_pair(-(self.platt_a * (z @ self.coef + self.intercept) + self.platt_b)), axis=1
        )
        self.training_metrics = {
            "train_frames": int(y.size),
            "train_trials": len(batches),
            "train_balanced_accuracy": balanced_accuracy(y, train_pred),
            "train_time_s": time.perf_counter() - started,
            "convergence_warnings": unconverged,
        }

    def _calibration_splits(
        self, has_contact: Sequence[bool], groups: np.ndarray
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        # Folds of whole trials, stratified by whether a trial has contact: grouping keeps
        # a trial's correlated frames on one side, and stratifying keeps both classes in
        # every training part (plain GroupKFold packs the longer contact trials together).
        flags = np.asarray(has_contact, dtype=bool)
        folds = min(self.config.calibration_folds, int(flags.sum()))
        if folds < 2:
            raise ValueError("Platt calibration needs at least two trials with contact")
        rng = np.random.default_rng(self._seed)
        fold_of = np.empty(flags.size, dtype=np.int64)
        for kind in (True, False):
            ids = np.flatnonzero(flags == kind)
            fold_of[ids[rng.permutation(ids.size)]] = np.arange(ids.size) % folds
        frame_fold = fold_of[groups]
        return [
            (np.flatnonzero(frame_fold != k), np.flatnonzero(frame_fold == k)) for k in range(folds)
        ]

    def metadata(self) -> dict[str, Any]:
        """What ``model.json`` holds."""
        return {
            "format": SVM_FORMAT,
            "format_version": _FORMAT_VERSION,
            "versions": {
                "hapticframe": version_of("hapticframe"),
                "scikit-learn": version_of("scikit-learn"),
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
            "config": self.config.model_dump(mode="json", exclude={"model_dir"}),
            "inputs": dict(self.groups),
            "classes": list(CLASSES),
            "fitted": self.fitted,
            "intercept": self.intercept,
            "platt_a": self.platt_a,
            "platt_b": self.platt_b,
            "training_metrics": self.training_metrics,
        }

    def training_report(self) -> dict[str, Any]:
        """What the last fit did (:class:`hapticframe.kinds.Trainable`): a copy of
        :attr:`training_metrics`, also when they were read from a saved model; empty before."""
        return dict(self.training_metrics)

    def save(self, directory: str | Path) -> Path:
        """Write ``model.npz`` (coef, mean, spread) and ``model.json`` into ``directory``."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        save_npz(out / "model.npz", compressed=False, coef=self.coef, mean=self.mean,
                 spread=self.spread)
        atomic_write(out / "model.json", json.dumps(self.metadata(), indent=2, allow_nan=False))
        return out

    def load(self, directory: str | Path) -> None:
        """Read a model written by :meth:`save` (no pickles), checked whole first.

        ``model.json`` must match :class:`~._persist.SVMModelFile` (strict types, finite
        Platt parameters) and its config :class:`LinearSVMConfig`; ``model.npz``'s arrays
        must have the declared width (checked from the headers before reading), finite
        values and a positive spread; a model whose score or Platt slope is zero (the
        same probability for every frame) is refused.

        Raises
        ------
        ValueError
            Naming the file that is missing, truncated, of another format, or does not fit.
        """
        path = Path(directory)
        meta_path, arrays_path = path / "model.json", path / "model.npz"
        meta = read_json_object(meta_path)
        if meta.get("format") != SVM_FORMAT or meta.get("format_version") != _FORMAT_VERSION:
            raise ValueError(f"{meta_path} is not a {SVM_FORMAT} v{_FORMAT_VERSION} file")
        try:
            record = SVMModelFile.model_validate(meta)
        except ValidationError as exc:
            raise schema_error(meta_path, exc) from None
        config = validate_config(meta_path, LinearSVMConfig, {**record.config, "model_dir": None})
        inputs = dict(record.inputs)
        if inputs != dict(config.inputs):
            raise ValueError(
                f"{meta_path}: inputs {inputs} differ from the config's {dict(config.inputs)}"
            )
        width = sum(inputs.values())
        if width > MAX_SVM_WIDTH:
            raise ValueError(f"{meta_path}: the inputs total {width} values; the limit is "
                             f"{MAX_SVM_WIDTH}")
        arrays = read_npz_arrays(arrays_path, {k: (width,) for k in ("coef", "mean", "spread")})
        if not (arrays["spread"] > 0).all():
            raise ValueError(f"{arrays_path}: spread holds zero or negative values; the inputs "
                             "are divided by it")
        for where, name, zero in ((arrays_path, "coef", not arrays["coef"].any()),
                                  (meta_path, "platt_a", record.platt_a == 0)):
            if zero:
                raise ValueError(
                    f"{where}: {name} is zero, so every frame would get the same probability"
                )
        self.config = config
        self.groups = inputs
        self.coef, self.mean, self.spread = arrays["coef"], arrays["mean"], arrays["spread"]
        self.intercept = record.intercept
        self.platt_a, self.platt_b = record.platt_a, record.platt_b
        self.fitted = record.fitted
        self.training_metrics = dict(record.training_metrics)

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        metrics: dict[str, Any] = {}
        for what, counts in self.fill_report.as_dict().items():
            for name, count in counts.items():
                metrics[f"{self.id}_{name}_{what}"] = count
        return metrics
