"""Classifier of free movement, jamming and contact in units of the movement's own drag.

The force (its magnitude, or one component's absolute value: ``force_component``) is
low-pass filtered and differentiated by the same :class:`ForceRateTracker` as the
``force-rate-jamming`` classifier; :class:`~hapticframe_jamming._drag_functional.DragTracker`
estimates the movement's free drag and accumulates the CUSUM of ``log(f / drag)``. Outputs
are the probabilities of ``("free", "jamming", "contact")``, the classes of
``force-rate-jamming``, so sensor models and maps take either.

Every row runs the same plain-float code whatever the chunking (the drag estimate of a
sample depends on the CUSUM of the one before), so streaming and batch agree bit for bit.
Invalid or non-finite samples are held as in ``force-rate-jamming``; rows before the first
valid sample get uniform probabilities (arg-max: free). During a movement's warm-up (the
drag not yet estimated) a row is that of a force equal to the drag (free), unless an
earlier movement of the run carried its drag over (``carry_drag``): then the row is judged
against the largest drag seen so far.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from hapticframe import atomic_write
from hapticframe.artifacts import read_json_object, schema_error
from hapticframe.filters import butterworth_sos
from hapticframe.kinds import (
    BuildContext,
    Classifier,
    ClassProbabilities,
    MovementResult,
    SampleBatch,
)

from . import _drag_functional as D
from . import _functional as F
from ._classifier import CLASSES, DEFAULT_SAMPLE_RATE_HZ, ForceRateTracker, TrackerState
from ._drag_config import DragRatioJammingConfig

__all__ = [
    "DRAG_RATIO_FILE",
    "DRAG_RATIO_FORMAT",
    "DragRatioJammingClassifier",
    "DragTrace",
]

#: What :meth:`DragRatioJammingClassifier.save` writes, and its format tag.
DRAG_RATIO_FILE = "drag_ratio.json"
DRAG_RATIO_FORMAT = "hapticframe-drag-ratio-jamming"
_FORMAT_VERSION = 1
#: The fields ``fit`` chooses (and ``save`` writes).
FITTED_FIELDS = ("drift", "cusum_threshold", "contact_ratio", "contact_ratio_rate_per_s",
                 "warmup_min_s")
#: The fields the fitted thresholds only mean something through.
_SETTING_FIELDS = ("force_component", "cutoff_hz", "filter_order", "settle_window_s",
                   "settle_fraction", "warmup_max_s", "tracking_time_s",
                   "min_drag_n")
_UNIFORM = (1.0 / 3, 1.0 / 3, 1.0 / 3)


@dataclass(frozen=True)
class DragTrace:
    """Per sample of one recording: filtered force, drag estimate (NaN in the warm-up),
    ratio, ratio rate (1/s), CUSUM, whether the detector was armed, and the probabilities."""

    timestamps_s: NDArray[np.float64]
    force: NDArray[np.float64]
    drag: NDArray[np.float64]
    ratio: NDArray[np.float64]
    ratio_rate_per_s: NDArray[np.float64]
    cusum: NDArray[np.float64]
    armed: NDArray[np.bool_]
    probabilities: NDArray[np.float64]


class DragRatioJammingClassifier(Classifier):
    """Free / jamming / contact from force relative to the movement's own free drag.

    Parameters
    ----------
    config : DragRatioJammingConfig
    context : BuildContext
        An input sensor, if given, supplies the sample rate when the config leaves it unset.
    """

    def __init__(self, config: DragRatioJammingConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if config.sample_rate_hz is not None:
            self._sample_rate_hz = float(config.sample_rate_hz)
        else:
            info = context.input_channel(config.force_channel)
            self._sample_rate_hz = DEFAULT_SAMPLE_RATE_HZ if info is None else float(info.rate_hz)
        self._training: dict[str, Any] = {}
        if config.model_dir is not None:
            self.load(config.model_dir)
        else:
            self._build()

    def _build(self) -> None:
        cfg = self.config
        try:
            sos = butterworth_sos(cfg.cutoff_hz, self._sample_rate_hz, cfg.filter_order)
        except ValueError as exc:
            raise ValueError(f"classifier {self.id!r}: {exc}") from exc
        self._filter = ForceRateTracker(sos, cfg.restart_after_gap_s)
        self._drag = D.DragTracker(D.DragSettings(
            settle_window_s=cfg.settle_window_s, settle_fraction=cfg.settle_fraction,
            warmup_min_s=cfg.warmup_min_s, warmup_max_s=cfg.warmup_max_s,
            tracking_time_s=cfg.tracking_time_s, min_drag=cfg.min_drag_n,
            max_dt_s=cfg.restart_after_gap_s, drift=cfg.drift))
        self._rule = D.Rule(cfg.cusum_threshold, cfg.cusum_scale, cfg.contact_ratio,
                            cfg.contact_ratio_rate_per_s, cfg.ratio_scale,
                            cfg.ratio_rate_scale_per_s)
        self._component = None if cfg.force_component == "magnitude" else int(cfg.force_component)

    # --- Classifier interface ------------------------------------------------------------

    @property
    def classes(self) -> tuple[str, ...]:
        return CLASSES

    @property
    def sample_rate_hz(self) -> float:
        """Rate the low-pass filter was designed for."""
        return self._sample_rate_hz

    def reset(self) -> None:
        # The run loop resets at every movement's start: the carried drag stays.
        self._filter.reset()
        self._drag.reset()

    def checkpoint(self) -> tuple[TrackerState, D.DragTrackerState]:
        return self._filter.snapshot(), self._drag.snapshot()

    def rewind(self, checkpoint: tuple[TrackerState, D.DragTrackerState]) -> None:
        self._filter.restore(checkpoint[0])
        self._drag.restore(checkpoint[1])

    def on_movement_end(self, result: MovementResult) -> None:
        # Each movement has its own drag (depth, sand, start-up): estimated afresh; the
        # largest so far guards the next one's warm-up (config.carry_drag).
        self._filter.reset()
        if self.config.carry_drag:
            self._drag.end_movement()
        else:
            self._drag.reset()

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        rows = self._rows(batch)
        return ClassProbabilities(batch.timestamps_s, rows[-1], CLASSES)

    def trace(self, batch: SampleBatch) -> DragTrace:
        """The detector's inner signals over a whole recording, from a fresh state (no
        carried drag); the classifier's own state is left as it was."""
        state = self.checkpoint()
        self._filter.reset()
        self._drag.forget()
        try:
            force, drag, ratio, rate, cusum, armed, probabilities = self._rows(batch)
        finally:
            self.rewind(state)
        return DragTrace(batch.timestamps_s, force, drag, ratio, rate, cusum, armed,
                         probabilities)

    def _magnitudes(self, batch: SampleBatch) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        name = self.config.force_channel
        if name not in batch.channels:
            raise ValueError(
                f"classifier {self.id!r}: input has no channel {name!r} "
                f"(channels: {sorted(batch.channels)}); set config.force_channel"
            )
        n = len(batch)
        values = batch.channels[name].reshape(n, -1) if n else np.empty((0, 1))
        if self._component is None:
            magnitude = F.force_magnitude(values) if n else np.empty(0)
        else:
            if values.shape[1] <= self._component:
                raise ValueError(
                    f"classifier {self.id!r}: force_component {self._component} but channel "
                    f"{name!r} has {values.shape[1]} component(s)"
                )
            magnitude = np.minimum(np.abs(values[:, self._component]), F.MAX_FORCE_N)
        valid = np.asarray(batch.valid.get(name, np.ones(n, dtype=bool)), dtype=bool)
        return np.asarray(magnitude, dtype=np.float64), valid & np.isfinite(magnitude)

    def _rows(self, batch: SampleBatch) -> tuple[NDArray[Any], ...]:
        """Every row through the filter and the drag tracker, one at a time."""
        magnitude, valid = self._magnitudes(batch)
        n = len(batch)
        times = batch.timestamps_s
        out_force = np.full(n, np.nan)
        out_drag = np.full(n, np.nan)
        out_ratio = np.ones(n)
        out_rate = np.zeros(n)
        out_cusum = np.zeros(n)
        out_armed = np.zeros(n, dtype=bool)
        probabilities = np.empty((n, len(CLASSES)))
        t_list, m_list, v_list = times.tolist(), magnitude.tolist(), valid.tolist()
        tracker, drag, rule = self._filter, self._drag, self._rule
        for i in range(n):
            filtered = tracker.process_one(t_list[i], m_list[i]) if v_list[i] else None
            if filtered is None:
                f, r, ok = tracker.process(times[i:i + 1], magnitude[i:i + 1], valid[i:i + 1])
                if not ok[0]:
                    probabilities[i] = _UNIFORM
                    continue
                filtered = (float(f[0]), float(r[0]))
            force, rate = filtered
            prior = drag.drag
            armed, ratio, ratio_rate, cusum = drag.step(t_list[i], force, rate)
            out_force[i] = force
            if armed and prior is not None:
                out_drag[i] = prior
            out_ratio[i], out_rate[i], out_cusum[i], out_armed[i] = ratio, ratio_rate, cusum, armed
            probabilities[i] = D.probabilities_row(armed, ratio, ratio_rate, cusum, rule)
        return out_force, out_drag, out_ratio, out_rate, out_cusum, out_armed, probabilities

    # --- training ------------------------------------------------------------------------

    def fit(self, batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> None:
        """Fit the drift, the CUSUM level and the contact thresholds on labelled movements
        (one recording each; labels 0 free, 1 jamming, 2 contact) so that free raking raises
        at most ``false_alarms_per_m`` alarms per metre; see
        :func:`hapticframe_jamming.calibrate_drag_ratio`."""
        from ._drag_calibration import calibrate_drag_ratio

        config, report = calibrate_drag_ratio(batches, labels, base_config=self.config,
                                              sample_rate_hz=self._sample_rate_hz)
        self.config = config
        self._build()
        self._training = report

    def training_report(self) -> dict[str, Any]:
        """What the last fit did: the thresholds, the false alarms per metre it reached on
        the recordings and the approaches it flagged early; empty before a fit."""
        return dict(self._training)

    # --- Persistent ------------------------------------------------------------------------

    def _settings(self) -> dict[str, Any]:
        cfg = self.config
        out: dict[str, Any] = {k: getattr(cfg, k) for k in _SETTING_FIELDS}
        out["sample_rate_hz"] = float(self._sample_rate_hz)
        return out

    def save(self, directory: str | Path) -> Path:
        """Write the fitted thresholds, the settings they hold for and the training report
        into ``directory/drag_ratio.json`` (plain JSON); returns its path."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        record = {
            "format": DRAG_RATIO_FORMAT,
            "format_version": _FORMAT_VERSION,
            "thresholds": {k: float(getattr(self.config, k)) for k in FITTED_FIELDS},
            "settings": self._settings(),
            "force_channel": self.config.force_channel,
            "training_report": self._training,
        }
        target = out / DRAG_RATIO_FILE
        atomic_write(target, json.dumps(record, indent=2, allow_nan=False))
        return target

    def load(self, directory: str | Path) -> None:
        """Read what :meth:`save` wrote; a ValueError naming the file when it does not fit
        (another format, bad values, or settings that differ from this config's)."""
        path = Path(directory) / DRAG_RATIO_FILE
        try:
            record = read_json_object(path)
        except ValueError as exc:
            raise ValueError(
                f"classifier {self.id!r}: no drag-ratio thresholds in {directory}: {exc}"
            ) from None
        if record.get("format") != DRAG_RATIO_FORMAT or record.get("format_version") != (
            _FORMAT_VERSION
        ):
            raise ValueError(f"classifier {self.id!r}: {path} is not a {DRAG_RATIO_FORMAT} "
                             f"v{_FORMAT_VERSION} file")
        try:
            saved = _DragFile.model_validate(record)
        except ValidationError as exc:
            raise ValueError(
                f"classifier {self.id!r}: bad drag-ratio thresholds: {schema_error(path, exc)}"
            ) from None
        ours = self._settings()
        theirs = saved.settings.model_dump()
        mismatched = [
            f"{key} {theirs[key]!r} (saved) vs {value!r} (configured)"
            for key, value in ours.items()
            if (theirs[key] != value if isinstance(value, str)
                else not math.isclose(float(theirs[key]), float(value), rel_tol=1e-9))
        ]
        if mismatched:
            raise ValueError(
                f"classifier {self.id!r}: the thresholds in {path} were fitted with other "
                f"settings: {'; '.join(mismatched)}. Configure the same or refit"
            )
        try:
            config = type(self.config).model_validate(
                {**self.config.model_dump(), **saved.thresholds.model_dump()}
            )
        except ValueError as exc:
            raise ValueError(f"classifier {self.id!r}: bad thresholds in {path}: {exc}") from exc
        self.config = config
        self._training = dict(saved.training_report)
        self._build()


_Finite = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class _Thresholds(_Strict):
    drift: Annotated[float, Field(allow_inf_nan=False, ge=0, le=10)]
    cusum_threshold: Annotated[float, Field(allow_inf_nan=False, ge=0, le=1e3)]
    contact_ratio: Annotated[float, Field(allow_inf_nan=False, ge=0, le=1e6)]
    contact_ratio_rate_per_s: _Finite
    warmup_min_s: Annotated[float, Field(allow_inf_nan=False, ge=0, le=600)]


class _Settings(_Strict):
    force_component: Literal["magnitude", "0", "1", "2"]
    cutoff_hz: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    filter_order: Annotated[int, Field(ge=1, le=4)]
    settle_window_s: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    settle_fraction: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    warmup_max_s: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    tracking_time_s: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    min_drag_n: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    sample_rate_hz: Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _DragFile(_Strict):
    """``drag_ratio.json`` (format version 1)."""

    format: Literal["hapticframe-drag-ratio-jamming"]
    format_version: Literal[1]
    thresholds: _Thresholds
    settings: _Settings
    force_channel: Annotated[str, Field(max_length=200)]
    training_report: dict[str, Any]
