"""Learning the force/force-rate thresholds from labelled runs, and measuring detection."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hapticframe.kinds import BuildContext, SampleBatch

from . import _functional as F
from ._classifier import DEFAULT_SAMPLE_RATE_HZ, ForceRateJammingClassifier
from ._config import ForceRateJammingConfig

__all__ = ["DetectionReport", "calibrate_thresholds", "evaluate_detection"]


def _check_pairs(batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> list[np.ndarray]:
    if len(batches) != len(labels):
        raise ValueError(f"got {len(batches)} batches but {len(labels)} label arrays")
    out = []
    for i, (batch, y) in enumerate(zip(batches, labels, strict=True)):
        y = np.asarray(y)
        if y.shape != (len(batch),):
            raise ValueError(f"labels[{i}] has shape {y.shape}, expected ({len(batch)},)")
        out.append(y.astype(np.int64))
    return out


def _classifier(
    config: ForceRateJammingConfig, sample_rate_hz: float | None
) -> ForceRateJammingClassifier:
    rate = sample_rate_hz or config.sample_rate_hz or DEFAULT_SAMPLE_RATE_HZ
    # model_dir None: calibration starts from the thresholds given, never from an artifact.
    config = type(config).model_validate(
        {**config.model_dump(), "sample_rate_hz": rate, "model_dir": None}
    )
    return ForceRateJammingClassifier(
        config, BuildContext(id="calibration", rng=np.random.default_rng(0))
    )


def calibrate_thresholds(
    batches: Sequence[SampleBatch],
    labels: Sequence[ArrayLike],
    base_config: ForceRateJammingConfig | None = None,
    sample_rate_hz: float | None = None,
    n_candidates: int = 96,
    objective: str = "events",
) -> ForceRateJammingConfig:
    """Thresholds that maximise balanced accuracy on labelled recordings.

    Each recording (one exploratory movement) is filtered from a fresh state exactly as the
    classifier does. The jamming thresholds then maximise balanced accuracy of each
    movement's first alarm (``objective="events"``: free stretches without alarm vs approaches
    first flagged during jamming) or of single samples (``"samples"``); the contact thresholds
    (when contact samples exist) maximise per-sample three-class balanced accuracy. The
    search runs over per-class quantiles of force and rate and is deterministic. With
    ``base_config.calibration_force_floor == "free-drag"`` the jamming force threshold
    cannot fall below the recordings' largest free-sand drag
    (:func:`hapticframe_jamming._functional.free_drag_floor`). See
    :func:`hapticframe_jamming._functional.best_and_thresholds`.

    Parameters
    ----------
    batches : sequence of SampleBatch
        Recordings holding the force channel named in the config.
    labels : sequence of (n_i,) int arrays
        Per-sample truth: 0 free, 1 jamming, 2 contact (e.g. a sandbox robot's ground truth).
    base_config : ForceRateJammingConfig or None
        Filter settings, scales and channel to keep; contact thresholds are kept from it when
        no contact samples exist. None uses the defaults.
    sample_rate_hz : float or None
        Overrides the config's filter sample rate (default 100 Hz when neither gives one).
    n_candidates : int
        Quantile candidates per class and axis.
    objective : {"events", "samples"}
        What balanced accuracy is measured on. ``"events"`` (default) matches how the run
        loop uses the classifier: it halts at the first alarm.

    Returns
    -------
    ForceRateJammingConfig
        ``base_config`` with the four thresholds replaced.
    """
    base = base_config or ForceRateJammingConfig()
    ys = _check_pairs(batches, labels)
    if not batches:
        raise ValueError("calibration needs at least one labelled recording")
    classifier = _classifier(base, sample_rate_hz)
    recordings: list[F.Recording] = [
        (*classifier.force_and_rate(batch), y) for batch, y in zip(batches, ys, strict=True)
    ]
    floor = (F.free_drag_floor(recordings)
             if base.calibration_force_floor == "free-drag" else None)
    thresholds, _ = F.best_and_thresholds(
        recordings, n_candidates=n_candidates, base=classifier.thresholds, objective=objective,
        force_floor=floor,
    )
    fj, rj, fc, rc = thresholds
    # model_validate, not model_copy(update=...): the new values get validated too.
    return type(base).model_validate(
        {
            **base.model_dump(),
            "jamming_force_n": fj,
            "jamming_rate_n_per_s": rj,
            "contact_force_n": fc,
            "contact_rate_n_per_s": rc,
        }
    )


@dataclass(frozen=True)
class DetectionReport:
    """How a classifier's first non-free decision per movement relates to the truth.

    A movement "approaches" an object when its labels contain jamming or contact. For each
    approach the first sample classified as non-free is ``early`` when the truth there is
    jamming (before contact), ``late`` when it is contact, a ``false_alarm`` when it is free
    movement, and ``missed`` when no sample is flagged. Movements with only free labels count
    as ``free_movements``, with ``free_false_alarms`` of them flagged at some sample.
    """

    approaches: int
    early: int
    late: int
    missed: int
    false_alarm: int
    free_movements: int
    free_false_alarms: int
    free_samples: int
    free_samples_flagged: int
    mean_lead_time_s: float

    @property
    def early_fraction(self) -> float:
        return self.early / self.approaches if self.approaches else float("nan")

    @property
    def free_sample_false_alarm_rate(self) -> float:
        return self.free_samples_flagged / self.free_samples if self.free_samples else float("nan")


def evaluate_detection(
    classifier: ForceRateJammingClassifier,
    batches: Sequence[SampleBatch],
    labels: Sequence[ArrayLike],
) -> DetectionReport:
    """Score a classifier's first decision per movement against per-sample truth.

    Each recording is classified from a fresh state (the batch path), which equals what a
    closed-loop run sees up to the moment it halts. ``mean_lead_time_s`` averages, over early
    detections whose recording later reached contact, the time from detection to contact.
    Free-sample counts use every free-labelled sample, including those after a detection.
    """
    ys = _check_pairs(batches, labels)
    counts = {"approaches": 0, "early": 0, "late": 0, "missed": 0, "false_alarm": 0}
    free_moves = free_flagged = free_samples = free_samples_flagged = 0
    leads = []
    for batch, y in zip(batches, ys, strict=True):
        predicted = classifier.predict(batch) if len(batch) else np.zeros(0, dtype=np.int64)
        free_samples += int(np.sum(y == 0))
        free_samples_flagged += int(np.sum((y == 0) & (predicted != 0)))
        flagged = np.flatnonzero(predicted != 0)
        if not np.any(y >= 1):
            free_moves += 1
            free_flagged += int(flagged.size > 0)
            continue
        counts["approaches"] += 1
        if flagged.size == 0:
            counts["missed"] += 1
            continue
        first = int(flagged[0])
        truth = int(y[first])
        counts[("false_alarm", "early", "late")[truth]] += 1
        contact = np.flatnonzero(y == 2)
        if truth == 1 and contact.size:
            leads.append(batch.timestamps_s[contact[0]] - batch.timestamps_s[first])
    return DetectionReport(
        **counts,
        free_movements=free_moves,
        free_false_alarms=free_flagged,
        free_samples=free_samples,
        free_samples_flagged=free_samples_flagged,
        mean_lead_time_s=float(np.mean(leads)) if leads else float("nan"),
    )
