"""Fitting the drag-ratio detector on labelled movements: a false-alarm budget per metre."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import BuildContext, SampleBatch

from . import _drag_functional as D
from . import _functional as F
from ._classifier import DEFAULT_SAMPLE_RATE_HZ
from ._drag_classifier import DragRatioJammingClassifier, DragTrace
from ._drag_config import DragRatioJammingConfig

__all__ = ["DRIFT_CANDIDATES", "LEVEL_CANDIDATES", "WARMUP_CANDIDATES", "OperatingPoint",
           "calibrate_drag_ratio", "operating_points"]

#: Drifts tried by ``fit``: forces 2 % to 100 % above the drag, as log-ratios.
DRIFT_CANDIDATES = tuple(float(v) for v in np.log1p(
    [0.03, 0.06, 0.1, 0.13, 0.16, 0.2, 0.25, 0.3, 0.4, 0.6, 1.0]))
#: The loosest contact thresholds fit may choose: force / drag, and force rate / drag (1/s).
MIN_CONTACT_RATIO = 2.0
MIN_CONTACT_RATE = 5.0
#: Minimum warm-ups tried (s): the start-up of the rig and sand at hand.
WARMUP_CANDIDATES = (0.5, 0.8, 1.1, 1.5)
#: CUSUM levels tried (log-ratio x s): 0 (a plain ratio threshold) and 1e-4 to 3.
LEVEL_CANDIDATES = (0.0, *(float(v) for v in np.geomspace(1e-4, 3.0, 46)))


@dataclass(frozen=True)
class OperatingPoint:
    """What one (drift, CUSUM level) does on the recordings."""

    drift: float
    cusum_threshold: float
    warmup_min_s: float
    false_alarms: int
    free_distance_m: float
    approaches: int
    early: int
    mean_lead_m: float

    @property
    def false_alarms_per_m(self) -> float:
        return self.false_alarms / self.free_distance_m if self.free_distance_m > 0 else 0.0


def _classifier(config: DragRatioJammingConfig, sample_rate_hz: float | None,
                **changes: Any) -> DragRatioJammingClassifier:
    rate = sample_rate_hz or config.sample_rate_hz or DEFAULT_SAMPLE_RATE_HZ
    config = type(config).model_validate(
        {**config.model_dump(), "sample_rate_hz": rate, "model_dir": None, **changes})
    return DragRatioJammingClassifier(
        config, BuildContext(id="calibration", rng=np.random.default_rng(0)))


def _step_s(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """Time each sample stands for (its step from the one before; the first the median)."""
    if t.size < 2:
        return np.zeros(t.size)
    d = np.diff(t)
    return np.concatenate([[float(np.median(d))], d])


def _contact_thresholds(traces: Sequence[DragTrace], ys: Sequence[NDArray[np.int64]],
                        base: tuple[float, float]) -> tuple[float, float]:
    """Ratio and ratio rate whose AND rule best separates contact from the rest (per-sample
    balanced accuracy over free, jamming and contact, armed samples only; at least
    :data:`MIN_CONTACT_RATIO` and :data:`MIN_CONTACT_RATE`); ``base`` when no contact was
    recorded."""
    armed = np.concatenate([tr.armed for tr in traces])
    y = np.concatenate(ys)[armed]
    if not np.any(y == 2) or not np.any(y != 2):
        return base
    ratio = np.concatenate([tr.ratio for tr in traces])[armed]
    rate = np.concatenate([tr.ratio_rate_per_s for tr in traces])[armed]
    r_cand = F.candidate_thresholds(ratio, y, 48)
    q_cand = F.candidate_thresholds(rate, y, 48)
    groups = [y == c for c in (0, 1, 2) if np.any(y == c)]
    counts = F.quadrant_counts(ratio, rate, groups, r_cand, q_cand)
    score = np.zeros((r_cand.size, q_cand.size))
    for members, above in zip(groups[:-1], counts[:-1], strict=True):
        score += 1.0 - above / members.sum()
    score += counts[-1] / groups[-1].sum()  # the contact group (last)
    # Contact is a spring: it at least doubles the drag within a millimetre or two and
    # rises at several drags per second. Looser thresholds let the start-up ramp (checked
    # for contact during the warm-up) or a noisy rate in free sand decide.
    allowed = (r_cand[:, None] >= MIN_CONTACT_RATIO) & (q_cand[None, :] >= MIN_CONTACT_RATE)
    score = np.where(allowed, score, -np.inf)
    if not np.isfinite(score).any():
        return base
    i, j = F.plateau_argmax(score)
    return float(r_cand[i]), float(q_cand[j])


def operating_points(traces: Sequence[DragTrace], ys: Sequence[NDArray[np.int64]],
                     drift: float, warmup_min_s: float, speed_m_per_s: float,
                     contact: Sequence[NDArray[np.bool_]] | None = None,
                     levels: Sequence[float] = LEVEL_CANDIDATES) -> list[OperatingPoint]:
    """False alarms and early detections of each CUSUM level on traces run at ``drift``.

    A false alarm is an alarm onset (jamming or contact flagged where the sample before was
    not) on an armed, free-labelled sample; the free distance counts armed free samples at
    ``speed_m_per_s``. An approach (a recording with jamming or contact labels) is *early*
    when its first flag falls on a jamming-labelled sample; its lead is the distance from
    there to the first contact label (approaches that reach contact).
    """
    free_m = sum(float(np.sum(_step_s(tr.timestamps_s)[tr.armed & (y == 0)]))
                 for tr, y in zip(traces, ys, strict=True)) * speed_m_per_s
    points = []
    for level in levels:
        alarms = approaches = early = 0
        leads = []
        for k, (tr, y) in enumerate(zip(traces, ys, strict=True)):
            flagged = tr.armed & (tr.cusum > level)
            if contact is not None:
                flagged = flagged | contact[k]
            alarms += D.alarm_onsets(flagged, tr.armed & (y == 0))
            if not np.any(y >= 1):
                continue
            approaches += 1
            hits = np.flatnonzero(flagged)
            if hits.size and y[hits[0]] == 1:
                early += 1
                touched = np.flatnonzero(y == 2)
                if touched.size and touched[0] > hits[0]:
                    leads.append((tr.timestamps_s[touched[0]] - tr.timestamps_s[hits[0]])
                                 * speed_m_per_s)
        points.append(OperatingPoint(float(drift), float(level), float(warmup_min_s), alarms,
                                     free_m, approaches, early,
                                     float(np.mean(leads)) if leads else 0.0))
    return points


def calibrate_drag_ratio(
    batches: Sequence[SampleBatch],
    labels: Sequence[ArrayLike],
    base_config: DragRatioJammingConfig | None = None,
    sample_rate_hz: float | None = None,
    drifts: Sequence[float] = DRIFT_CANDIDATES,
    warmups_s: Sequence[float] = WARMUP_CANDIDATES,
) -> tuple[DragRatioJammingConfig, dict[str, Any]]:
    """The warm-up, drift and CUSUM level that flag the most approaches early within the
    false-alarm budget.

    For each candidate minimum warm-up and drift, every recording (one movement) is run
    from a fresh state and the contact thresholds are fitted on its ratios (when contact
    was recorded). Among the CUSUM levels whose false alarms on free raking stay within
    ``false_alarms_per_m`` times the free distance, the candidate with the most early
    detections wins, then the fewest false alarms, the longest mean lead, the shorter
    warm-up, and the larger (more conservative) drift and level. When none meets the
    budget the one with the fewest false alarms is taken and the report says
    ``budget_met: false``.

    Returns
    -------
    config : DragRatioJammingConfig
        ``base_config`` with ``drift``, ``cusum_threshold``, ``warmup_min_s``,
        ``contact_ratio`` and ``contact_ratio_rate_per_s`` replaced.
    report : dict
        Plain JSON values: the chosen thresholds and what they did on the recordings.
    """
    base = base_config or DragRatioJammingConfig()
    if len(batches) != len(labels):
        raise ValueError(f"got {len(batches)} batches but {len(labels)} label arrays")
    if not batches:
        raise ValueError("calibration needs at least one labelled recording")
    ys = []
    for i, (batch, y) in enumerate(zip(batches, labels, strict=True)):
        y = np.asarray(y)
        if y.shape != (len(batch),):
            raise ValueError(f"labels[{i}] has shape {y.shape}, expected ({len(batch)},)")
        y = y.astype(np.int64)
        if np.any((y < 0) | (y > 2)):
            raise ValueError(f"labels[{i}]: labels must be 0 (free), 1 (jamming) or 2 (contact)")
        ys.append(y)
    all_y = np.concatenate(ys)
    if not np.any(all_y == 0) or not np.any(all_y >= 1):
        raise ValueError("calibration needs both free (0) and interaction (1 or 2) samples")
    best: tuple[Any, ...] | None = None
    chosen: tuple[OperatingPoint, tuple[float, float]] | None = None
    for warmup in sorted({min(float(w), base.warmup_max_s) for w in warmups_s}):
        for drift in drifts:
            classifier = _classifier(base, sample_rate_hz, drift=float(drift),
                                     warmup_min_s=warmup)
            traces = [classifier.trace(b) for b in batches]
            contact_t = _contact_thresholds(traces, ys, (base.contact_ratio,
                                                         base.contact_ratio_rate_per_s))
            contact = [tr.armed & (tr.ratio > contact_t[0])
                       & (tr.ratio_rate_per_s > contact_t[1]) for tr in traces]
            for p in operating_points(traces, ys, float(drift), warmup, base.speed_m_per_s,
                                      contact):
                met = p.false_alarms <= base.false_alarms_per_m * p.free_distance_m
                # Within the budget: most early detections, then the fewest alarms (the
                # budget is a ceiling, not a target), the longest lead (to the cm), the
                # shorter warm-up and the more conservative drift and level.
                key = ((met, p.early, -p.false_alarms, round(p.mean_lead_m, 2),
                        -p.warmup_min_s, p.drift, p.cusum_threshold) if met else
                       (met, -p.false_alarms, p.early, round(p.mean_lead_m, 3),
                        -p.warmup_min_s, p.drift, p.cusum_threshold))
                if best is None or key > best:
                    best, chosen = key, (p, contact_t)
    assert chosen is not None and best is not None
    point, (contact_ratio, contact_rate) = chosen
    config = type(base).model_validate({
        **base.model_dump(), "drift": point.drift, "cusum_threshold": point.cusum_threshold,
        "warmup_min_s": point.warmup_min_s,
        "contact_ratio": contact_ratio, "contact_ratio_rate_per_s": contact_rate})
    report = {
        "recordings": len(batches), "samples": int(all_y.size),
        "drift": point.drift, "cusum_threshold": point.cusum_threshold,
        "warmup_min_s": point.warmup_min_s, "contact_ratio": contact_ratio,
        "contact_ratio_rate_per_s": contact_rate,
        "false_alarms": point.false_alarms, "free_distance_m": point.free_distance_m,
        "false_alarms_per_m": point.false_alarms_per_m,
        "budget_false_alarms_per_m": base.false_alarms_per_m, "budget_met": bool(best[0]),
        "approaches": point.approaches, "early": point.early,
        "mean_lead_m": point.mean_lead_m, "speed_m_per_s": base.speed_m_per_s,
    }
    return config, report
