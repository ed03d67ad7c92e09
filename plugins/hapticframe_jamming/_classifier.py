"""Force/force-rate classifier of free movement, granular jamming and direct contact.

The force magnitude is low-pass filtered (Butterworth, second-order sections with explicit
state) and differentiated over the sample timestamps; the pair (filtered force, force rate)
is placed against the thresholds of thesis Figure 3.4.

Speed
-----
The Butterworth sections are designed in numpy (:func:`hapticframe.filters.butterworth_sos`),
so building a classifier does not import ``scipy.signal`` (about 0.6 s), and a closed loop's
one-sample updates run the filter, the rate and the softmax in plain floats
(:meth:`ForceRateJammingClassifier._scalar_row`, about 10 µs instead of 0.45 ms). Batches of
up to :data:`ROW_BY_ROW_MAX` samples (a closed loop that looks ahead classifies a few dozen
steps at once) run the same plain-float code row by row, so they give bit for bit the numbers
of one-sample updates; longer batches (whole recordings) take the array path, which agrees to
rounding.

Invalid samples
---------------
A sample whose force is NaN or infinite, or that the batch marks invalid, is replaced by the
last valid force (sample-and-hold), so the filter and the rate carry on smoothly. Samples
before the first valid one get uniform probabilities (arg-max: "free") and leave the filter
uninitialised. The filter starts at rest on the first valid force, so a classifier switched
on mid-movement does not see a spurious step. After a gap of more than
``restart_after_gap_s`` without a valid force (a sensor replugged or resynchronising), the
filter starts again at rest on the next valid force: the force changed during the gap, and
the held value's jump to it would read as a force rate no sand produced.
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
from hapticframe.filters import butterworth_sos, sos_filter, sos_step_state
from hapticframe.kinds import (
    BuildContext,
    Classifier,
    ClassProbabilities,
    MovementResult,
    SampleBatch,
)

from . import _functional as F
from ._config import ForceRateJammingConfig

__all__ = [
    "CLASSES",
    "THRESHOLDS_FILE",
    "THRESHOLDS_FORMAT",
    "ForceRateJammingClassifier",
    "ForceRateTracker",
    "TrackerState",
]

CLASSES = ("free", "jamming", "contact")
#: What :meth:`ForceRateJammingClassifier.save` writes, and its format tag.
THRESHOLDS_FILE = "thresholds.json"
THRESHOLDS_FORMAT = "hapticframe-force-rate-jamming"
_FORMAT_VERSION = 1
_THRESHOLD_FIELDS = (
    "jamming_force_n",
    "jamming_rate_n_per_s",
    "contact_force_n",
    "contact_rate_n_per_s",
)
DEFAULT_SAMPLE_RATE_HZ = 100.0
#: Longest batch that :meth:`ForceRateJammingClassifier.update` classifies row by row.
ROW_BY_ROW_MAX = 4096


@dataclass(frozen=True)
class TrackerState:
    """The streaming state of a :class:`ForceRateTracker`, copied by its ``snapshot``."""

    zi: NDArray[np.float64] | None
    registers: list[list[float]] | None
    held: float | None
    last_y: float | None
    last_t: float | None
    last_seen_t: float
    last_valid_t: float


class ForceRateTracker:
    """Streaming low-pass filter and rate of a force magnitude, chunking-invariant.

    Parameters
    ----------
    sos : (k, 6) array
        Second-order sections of the low-pass filter.
    restart_after_gap_s : float
        A valid sample more than this long after the previous valid one restarts the filter
        at rest on it (its rate is 0); ``inf``: never.
    """

    def __init__(self, sos: NDArray[np.float64], restart_after_gap_s: float = math.inf) -> None:
        if not restart_after_gap_s > 0:
            raise ValueError(f"restart_after_gap_s must be positive, got {restart_after_gap_s}")
        self._sos = sos
        self._max_gap_s = float(restart_after_gap_s)
        # Plain-float copies for the one-sample path: (b0, b1, b2, a1, a2) per section (a0 = 1).
        self._sections = [
            (float(r[0]), float(r[1]), float(r[2]), float(r[4]), float(r[5])) for r in sos
        ]
        self.reset()

    def reset(self) -> None:
        self._zi: NDArray[np.float64] | None = None
        # The filter state as plain floats while one-sample updates run; when set, it is
        # the current state and _zi is stale (process() converts it back).
        self._registers: list[list[float]] | None = None
        self._held: float | None = None  # last valid raw magnitude
        self._last_y: float | None = None
        self._last_t: float | None = None  # time of the last filtered sample
        self._last_seen_t = -np.inf  # time of the last sample of any kind
        self._last_valid_t = -np.inf  # time of the last valid sample

    def snapshot(self) -> TrackerState:
        """The whole streaming state (copies), for :meth:`restore`."""
        return TrackerState(
            None if self._zi is None else self._zi.copy(),
            None if self._registers is None else [list(r) for r in self._registers],
            self._held,
            self._last_y,
            self._last_t,
            self._last_seen_t,
            self._last_valid_t,
        )

    def restore(self, snapshot: TrackerState) -> None:
        """Return to the state :meth:`snapshot` returned."""
        zi, registers = snapshot.zi, snapshot.registers
        self._zi = None if zi is None else np.array(zi, dtype=np.float64)
        self._registers = None if registers is None else [list(r) for r in registers]
        self._held = snapshot.held
        self._last_y = snapshot.last_y
        self._last_t = snapshot.last_t
        self._last_seen_t = snapshot.last_seen_t
        self._last_valid_t = snapshot.last_valid_t

    def process(
        self,
        timestamps_s: NDArray[np.float64],
        magnitude: NDArray[np.float64],
        valid: NDArray[np.bool_],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Filtered force, force rate and an "initialised" mask for the next samples.

        Rows before the first valid sample ever seen are NaN in both outputs and False in
        the mask.
        """
        t = np.asarray(timestamps_s, dtype=np.float64)
        n = t.size
        if n == 0:
            return np.empty(0), np.empty(0), np.zeros(0, dtype=bool)
        if t[0] <= self._last_seen_t:
            raise ValueError(
                f"timestamps must increase across updates: {t[0]} follows {self._last_seen_t}; "
                "call reset() before replaying a recording"
            )
        self._last_seen_t = float(t[-1])
        if self._registers is not None:
            self._zi = np.array(self._registers, dtype=np.float64)
            self._registers = None
        ok = valid & np.isfinite(magnitude)
        # Valid rows that follow a gap longer than the limit start a new segment.
        valid_t = t[ok]
        previous = np.concatenate([[self._last_valid_t], valid_t[:-1]])
        restarts = np.flatnonzero(ok)[(valid_t - previous > self._max_gap_s)
                                      & np.isfinite(previous)]
        if valid_t.size:
            self._last_valid_t = float(valid_t[-1])
        if not restarts.size:
            return self._segment(t, magnitude, ok)
        parts = []
        for a, b in zip(np.concatenate([[0], restarts]), np.concatenate([restarts, [n]]),
                        strict=True):
            if a in restarts:
                self._zi, self._last_y, self._last_t = None, None, None
            if b > a:
                parts.append(self._segment(t[a:b], magnitude[a:b], ok[a:b]))
        force, rate, initialised = (np.concatenate(p) for p in zip(*parts, strict=True))
        return force, rate, initialised

    def _segment(
        self, t: NDArray[np.float64], magnitude: NDArray[np.float64], ok: NDArray[np.bool_]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """:meth:`process` of rows without a restart (``ok``: valid and finite)."""
        n = t.size
        # Forward-fill: each row takes the latest valid value at or before it.
        source = np.maximum.accumulate(np.where(ok, np.arange(n), -1))
        before = np.nan if self._held is None else self._held
        held = np.where(source >= 0, magnitude[np.maximum(source, 0)], before)
        initialised = np.isfinite(held)
        force = np.full(n, np.nan)
        rate = np.full(n, np.nan)
        if not initialised.any():
            return force, rate, initialised
        start = int(np.argmax(initialised))  # initialised rows form a suffix
        if self._zi is None:
            # Start at rest on the first valid value: no step response from zero.
            self._zi = sos_step_state(self._sos) * held[start]
        y, self._zi = sos_filter(self._sos, held[start:], self._zi)
        previous_y = y[0] if self._last_y is None else self._last_y
        previous_t = t[start] - 1.0 if self._last_t is None else self._last_t
        force[start:] = y
        rate[start:] = np.diff(np.concatenate([[previous_y], y])) / np.diff(
            np.concatenate([[previous_t], t[start:]])
        )
        self._held = float(held[-1])
        self._last_y = float(y[-1])
        self._last_t = float(t[-1])
        return force, rate, initialised

    def process_one(self, t: float, magnitude: float) -> tuple[float, float] | None:
        """Filtered force and force rate of one valid, finite sample, in plain floats.

        The same recursion as :meth:`process` (transposed direct form II) without arrays,
        for a closed loop's one-sample updates. Returns None, changing nothing, when the
        sample needs :meth:`process`: the filter is not initialised yet, or ``t`` does not
        follow the previous sample (process() raises the error).
        """
        if self._last_y is None or self._last_t is None or t <= self._last_seen_t:
            return None
        if t - self._last_valid_t > self._max_gap_s:
            return None  # a restart after a gap: process() handles it
        registers = self._registers
        if registers is None:
            if self._zi is None:
                return None
            registers = self._registers = self._zi.tolist()
        self._last_seen_t = t
        self._last_valid_t = t
        sample = magnitude
        for (b0, b1, b2, a1, a2), section in zip(self._sections, registers, strict=True):
            y = b0 * sample + section[0]
            section[0] = b1 * sample - a1 * y + section[1]
            section[1] = b2 * sample - a2 * y
            sample = y
        rate = (sample - self._last_y) / (t - self._last_t)
        self._held = magnitude
        self._last_y = sample
        self._last_t = t
        return sample, rate


class ForceRateJammingClassifier(Classifier):
    """Classifies free movement, granular jamming and direct contact from force and force rate.

    Parameters
    ----------
    config : ForceRateJammingConfig
    context : BuildContext
        An input sensor, if given, supplies the sample rate when the config leaves it unset.

    Notes
    -----
    With ``config.model_dir`` the thresholds that :meth:`save` wrote there (after
    :meth:`fit`, e.g. by ``hapticframe train``) replace the configured ones at build time.
    """

    def __init__(self, config: ForceRateJammingConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._sample_rate_hz = self._resolve_sample_rate(config, context)
        self._training: dict[str, Any] = {}
        if config.model_dir is not None:
            self.load(config.model_dir)  # builds the filter too
        else:
            self._build()

    @staticmethod
    def _resolve_sample_rate(config: ForceRateJammingConfig, context: BuildContext) -> float:
        if config.sample_rate_hz is not None:
            return float(config.sample_rate_hz)
        info = context.input_channel(config.force_channel)
        return DEFAULT_SAMPLE_RATE_HZ if info is None else float(info.rate_hz)

    def _build(self) -> None:
        cfg = self.config
        try:
            sos = butterworth_sos(cfg.cutoff_hz, self._sample_rate_hz, cfg.filter_order)
        except ValueError as exc:
            raise ValueError(f"classifier {self.id!r}: {exc}") from exc
        self._tracker = ForceRateTracker(sos, cfg.restart_after_gap_s)
        # The thresholds with their softness scales, as plain floats for the one-sample path.
        self._rule = (*(float(v) for v in self.thresholds), float(cfg.force_scale_n),
                      float(cfg.rate_scale_n_per_s))

    # --- Classifier interface ------------------------------------------------------------

    @property
    def classes(self) -> tuple[str, ...]:
        return CLASSES

    @property
    def sample_rate_hz(self) -> float:
        """Rate the low-pass filter was designed for."""
        return self._sample_rate_hz

    @property
    def thresholds(self) -> F.Thresholds:
        """(jamming force, jamming rate, contact force, contact rate)."""
        cfg = self.config
        return (
            cfg.jamming_force_n,
            cfg.jamming_rate_n_per_s,
            cfg.contact_force_n,
            cfg.contact_rate_n_per_s,
        )

    def reset(self) -> None:
        self._tracker.reset()

    def checkpoint(self) -> TrackerState:
        """The filter state (the classifier keeps no other state between updates)."""
        return self._tracker.snapshot()

    def rewind(self, checkpoint: TrackerState) -> None:
        self._tracker.restore(checkpoint)

    def on_movement_end(self, result: MovementResult) -> None:
        # Each exploratory movement is a fresh approach: the last one's force says nothing.
        self.reset()

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        n = len(batch)
        channel = batch.channels.get(self.config.force_channel)
        if 0 < n <= ROW_BY_ROW_MAX and channel is not None and channel.size <= 3 * n:
            return self._update_rows(batch, channel)
        return self._update_array(batch)

    def _update_array(self, batch: SampleBatch) -> ClassProbabilities:
        force, rate, initialised = self._track(batch)
        probabilities = np.full((len(batch), len(CLASSES)), 1.0 / len(CLASSES))
        if initialised.any():
            probabilities[initialised] = F.state_probabilities(
                force[initialised],
                rate[initialised],
                self.thresholds,
                self.config.force_scale_n,
                self.config.rate_scale_n_per_s,
            )
        return ClassProbabilities(batch.timestamps_s, probabilities, CLASSES)

    def _update_rows(self, batch: SampleBatch, channel: NDArray[np.float64]) -> ClassProbabilities:
        """Each row as a one-sample update: the plain-float path where it applies, else the
        array path on that row alone."""
        n = len(batch)
        times = batch.timestamps_s.tolist()
        rows = channel.reshape(n, -1).tolist()
        valid = batch.valid.get(self.config.force_channel)
        flags = [True] * n if valid is None else [bool(v) for v in valid.tolist()]
        if n == 1:
            row = self._scalar_row(times[0], rows[0], flags[0])
            if row is None:
                return self._update_array(batch)
            return ClassProbabilities(batch.timestamps_s, np.array([row]), CLASSES)
        probabilities = np.empty((n, len(CLASSES)))
        for i in range(n):
            row = self._scalar_row(times[i], rows[i], flags[i])
            if row is None:
                single = self._update_array(batch.select(slice(i, i + 1)))
                probabilities[i] = single.probabilities[0]
            else:
                probabilities[i] = row
        return ClassProbabilities(batch.timestamps_s, probabilities, CLASSES)

    def _scalar_row(
        self, t: float, components: list[float], valid: bool
    ) -> tuple[float, float, float] | None:
        """Probabilities of one sample in plain floats (same numbers as the array path to
        rounding); None, changing nothing, when the sample needs the array path."""
        if not valid or len(components) > 3:
            return None
        magnitude = math.sqrt(sum([v * v for v in components]))
        if not (math.isfinite(magnitude) and magnitude <= F.MAX_FORCE_N):
            return None
        filtered = self._tracker.process_one(t, magnitude)
        if filtered is None:
            return None
        sample, rate = filtered
        fj, rj, fc, rc, force_scale, rate_scale = self._rule
        m_j = min((sample - fj) / force_scale, (rate - rj) / rate_scale)
        m_c = min((sample - fc) / force_scale, (rate - rc) / rate_scale)
        limit = F._MAX_LOGIT
        jam = min(max(m_j, -limit), limit)
        contact = min(max(m_c + max(m_j, 0.0), -limit), limit)
        top = max(0.0, jam, contact)
        w0, w1, w2 = math.exp(-top), math.exp(jam - top), math.exp(contact - top)
        total = w0 + w1 + w2
        return w0 / total, w1 / total, w2 / total

    def fit(self, batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> None:
        """Learn the four thresholds from labelled recordings, one per exploratory movement.

        See :func:`hapticframe_jamming.calibrate_thresholds` (event objective).
        """
        from ._calibration import calibrate_thresholds

        self.config = calibrate_thresholds(
            batches, labels, base_config=self.config, sample_rate_hz=self._sample_rate_hz
        )
        self._build()
        self._training = {
            "recordings": len(batches),
            "samples": sum(len(b) for b in batches),
            "jamming_force_n": self.config.jamming_force_n,
            "jamming_rate_n_per_s": self.config.jamming_rate_n_per_s,
            "contact_force_n": self.config.contact_force_n,
            "contact_rate_n_per_s": self.config.contact_rate_n_per_s,
        }

    def training_report(self) -> dict[str, Any]:
        """What the last fit did (:class:`hapticframe.kinds.Trainable`): the recordings it
        saw and the four thresholds it chose; empty before a fit."""
        return dict(self._training)

    # --- Persistent ------------------------------------------------------------------------

    def _filter_settings(self) -> dict[str, float]:
        return {
            "cutoff_hz": float(self.config.cutoff_hz),
            "filter_order": int(self.config.filter_order),
            "sample_rate_hz": float(self._sample_rate_hz),
        }

    def save(self, directory: str | Path) -> Path:
        """Write the four thresholds, the filter they were fitted through and the training
        report into ``directory/thresholds.json`` (plain JSON); returns its path."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        record = {
            "format": THRESHOLDS_FORMAT,
            "format_version": _FORMAT_VERSION,
            "thresholds": {name: float(getattr(self.config, name)) for name in _THRESHOLD_FIELDS},
            "filter": self._filter_settings(),
            "force_channel": self.config.force_channel,
            "training_report": self._training,
        }
        target = out / THRESHOLDS_FILE
        atomic_write(target, json.dumps(record, indent=2, allow_nan=False))
        return target

    def load(self, directory: str | Path) -> None:
        """Read the thresholds :meth:`save` wrote (ValueError naming the file when they do
        not fit).

        The file must match :class:`_ThresholdsFile` (strict JSON types, finite thresholds,
        no list where an object belongs). Thresholds on a filtered force rate are only
        meaningful through the filter they were fitted with, so the artifact is refused
        when its cutoff, order or sample rate differ from this classifier's.
        """
        path = Path(directory) / THRESHOLDS_FILE
        try:
            record = read_json_object(path)
        except ValueError as exc:
            raise ValueError(
                f"classifier {self.id!r}: no jamming thresholds in {directory}: {exc}"
            ) from None
        if record.get("format") != THRESHOLDS_FORMAT or record.get("format_version") != (
            _FORMAT_VERSION
        ):
            raise ValueError(
                f"classifier {self.id!r}: {path} is not a {THRESHOLDS_FORMAT} "
                f"v{_FORMAT_VERSION} file"
            )
        try:
            saved = _ThresholdsFile.model_validate(record)
        except ValidationError as exc:
            raise ValueError(
                f"classifier {self.id!r}: bad thresholds: {schema_error(path, exc)}"
            ) from None
        ours = self._filter_settings()
        mismatched = [
            f"{key} {getattr(saved.filter, key)!r} (saved) vs {value!r} (configured)"
            for key, value in ours.items()
            if not math.isclose(float(getattr(saved.filter, key)), value, rel_tol=1e-9)
        ]
        if mismatched:
            raise ValueError(
                f"classifier {self.id!r}: the thresholds in {path} were fitted through another "
                f"filter: {'; '.join(mismatched)}. Configure the same filter or refit"
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

    # --- extras ----------------------------------------------------------------------------

    def force_and_rate(self, batch: SampleBatch) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Filtered force and force rate of a whole recording, from a fresh state (batch path).

        Rows before the first valid sample are NaN.
        """
        self.reset()
        force, rate, _ = self._track(batch)
        self.reset()
        return force, rate

    def _track(
        self, batch: SampleBatch
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        name = self.config.force_channel
        if name not in batch.channels:
            raise ValueError(
                f"classifier {self.id!r}: input has no channel {name!r} "
                f"(channels: {sorted(batch.channels)}); set config.force_channel"
            )
        magnitude = F.force_magnitude(batch.channels[name]) if len(batch) else np.empty(0)
        valid = np.asarray(batch.valid.get(name, np.ones(len(batch), dtype=bool)), dtype=bool)
        return self._tracker.process(batch.timestamps_s, magnitude, valid)


# A threshold beyond the largest force the classifier reads could never be crossed.
_Threshold = Annotated[float, Field(allow_inf_nan=False, ge=-F.MAX_FORCE_N, le=F.MAX_FORCE_N)]


class _Strict(BaseModel):
    # JSON types as written (no "6.0" for 6.0, no true for 1); unknown fields are errors.
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class _Thresholds(_Strict):
    jamming_force_n: _Threshold
    jamming_rate_n_per_s: _Threshold
    contact_force_n: _Threshold
    contact_rate_n_per_s: _Threshold


class _Filter(_Strict):
    cutoff_hz: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    filter_order: Annotated[int, Field(ge=1, le=4)]
    sample_rate_hz: Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _ThresholdsFile(_Strict):
    """``thresholds.json`` (format version 1)."""

    format: Literal["hapticframe-force-rate-jamming"]
    format_version: Literal[1]
    thresholds: _Thresholds
    filter: _Filter
    force_channel: Annotated[str, Field(max_length=200)]
    training_report: dict[str, Any]
