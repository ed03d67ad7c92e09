"""The ``raking-estimator`` classifier: per-sample distance, direction and depth estimates."""

from __future__ import annotations

import itertools
import json
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import (
    BuildContext,
    Classifier,
    ClassProbabilities,
    MovementResult,
    RunOutcome,
    SampleBatch,
)

from ._config import RakingEstimatorConfig
from ._data import select_inputs
from ._model import EstimatorSettings, ObjectEstimate, RakingModel, TrainingTrial, fit_model

__all__ = ["RakingEstimator", "pretrained_model_dir"]

#: Standardised inputs are clipped to this many standard deviations (finite for any input).
_CLIP_SIGMAS = 50.0


def pretrained_model_dir() -> Path:
    """The shipped model (``data/pretrained``)."""
    return Path(str(resources.files("hapticframe_raking") / "data" / "pretrained"))


class RakingEstimator(Classifier):
    """Streams tactile forces; estimates the buried object's distance, direction, depth.

    Every input sample gets an estimate from the last ``window_steps`` samples (the first
    sample repeated before the stream's start). A sample whose forces are not all finite
    is replaced by the last finite one (before any, by the training mean) and counted.
    Classes are ``("far", "near")``; the full estimates are in :attr:`estimates` and a
    run's ``estimates.npz``.

    Parameters
    ----------
    config : RakingEstimatorConfig
    context : BuildContext
    """

    def __init__(self, config: RakingEstimatorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._model: RakingModel | None = None
        self._report: dict[str, Any] = {}
        if config.pretrained:
            self._model = RakingModel.load(pretrained_model_dir())
        elif config.model_dir is not None:
            self.load(config.model_dir)
        self.reset()

    @property
    def classes(self) -> tuple[str, ...]:
        return ("far", "near")

    @property
    def settings(self) -> EstimatorSettings:
        c = self.config
        return EstimatorSettings(c.input_set, c.window_steps, c.hidden_units, c.epochs,
                                 c.batch_size, c.learning_rate, c.skip_first_steps, c.range_mm)

    @property
    def model(self) -> RakingModel:
        if self._model is None:
            raise RuntimeError(f"raking-estimator {self.id!r} is not trained: run hapticframe "
                               "train, or set model_dir or pretrained: true")
        return self._model

    def reset(self) -> None:
        self._buffer: NDArray[np.float64] | None = None
        self._last_t = -np.inf
        self._last_valid: NDArray[np.float64] | None = None
        self._times: list[NDArray[np.float64]] = []
        self._estimates: list[ObjectEstimate] = []
        self._labels: list[dict[str, NDArray[np.float64]]] = []
        self.replaced_samples = 0

    # --- training -----------------------------------------------------------------------

    def _inputs(self, batch: SampleBatch) -> NDArray[np.float64]:
        name = self.config.force_channel
        if name not in batch.channels:
            raise ValueError(f"raking-estimator {self.id!r}: the input has no channel "
                             f"{name!r} (channels: {', '.join(batch.channels)})")
        force = np.asarray(batch.channels[name], dtype=np.float64)
        if force.shape[1:] != (4, 3):
            raise ValueError(f"raking-estimator {self.id!r}: {name!r} has per-sample shape "
                             f"{force.shape[1:]}, expected (4, 3) (4 taxels, x y z)")
        return select_inputs(force, self.config.input_set)

    def _label(self, batch: SampleBatch, name: str) -> NDArray[np.float64]:
        if name not in batch.channels:
            raise ValueError(f"raking-estimator {self.id!r}: the training recordings carry "
                             f"no label channel {name!r} (channels: {', '.join(batch.channels)})")
        return np.asarray(batch.channels[name], dtype=np.float64).reshape(len(batch))

    def fit(self, batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> None:
        """Train on recordings that carry the distance, direction and depth channels.

        ``labels`` (the run's ``label_channel``) is not used: the three label channels come
        with the inputs, named in the config.
        """
        c = self.config
        trials = [TrainingTrial(self._inputs(b), self._label(b, c.distance_channel),
                                np.rint(self._label(b, c.direction_channel)).astype(np.int64),
                                np.rint(self._label(b, c.depth_channel)).astype(np.int64))
                  for b in batches if len(b)]
        self._model, self._report = fit_model(trials, self.settings, self.context.rng,
                                              threads=c.train_threads)
        self.reset()

    def training_report(self) -> Mapping[str, Any]:
        return {k: v for k, v in self._report.items() if k != "losses"} | (
            {"losses": [round(x, 6) for x in self._report["losses"]]} if self._report else {})

    def save(self, directory: str | Path) -> None:
        self.model.save(directory)

    def load(self, directory: str | Path) -> None:
        model = RakingModel.load(directory)
        if model.settings.input_set != self.config.input_set or (
                model.settings.window_steps != self.config.window_steps):
            raise ValueError(f"{directory}: the saved model reads {model.settings.input_set} "
                             f"over {model.settings.window_steps} steps; the config says "
                             f"{self.config.input_set} over {self.config.window_steps}")
        self._model = model

    # --- streaming ----------------------------------------------------------------------

    def _clean(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        model = self.model
        out = np.array(x, dtype=np.float64)
        for i in range(len(out)):
            if np.all(np.isfinite(out[i])):
                self._last_valid = out[i]
            else:
                out[i] = self._last_valid if self._last_valid is not None else model.mean
                self.replaced_samples += 1
        lo = model.mean - _CLIP_SIGMAS * model.std
        hi = model.mean + _CLIP_SIGMAS * model.std
        clipped: NDArray[np.float64] = np.clip(out, lo, hi)
        return clipped

    def estimate(self, batch: SampleBatch) -> ObjectEstimate:
        """Streaming step: the estimates of this batch's samples (state kept).

        A gap of more than ``restart_after_gap_s`` before a sample starts a new window there
        (a new trial: nothing of the previous one is read).
        """
        x = self._clean(self._inputs(batch))
        t = np.asarray(batch.timestamps_s, dtype=np.float64)
        if len(x) == 0:
            return ObjectEstimate(np.empty(0), np.empty(0), np.empty((0, 3)), np.empty((0, 2)))
        gaps = np.diff(np.concatenate([[self._last_t], t])) > self.config.restart_after_gap_s
        self._last_t = float(t[-1])
        starts = np.flatnonzero(gaps)
        bounds = np.concatenate([[0], starts[starts > 0], [len(x)]])
        parts = []
        for lo, hi in itertools.pairwise(bounds):
            if gaps[lo]:
                self._buffer = None
            parts.append(self._windows(x[lo:hi]))
        est = self.model.estimate_windows(np.concatenate(parts))
        self._times.append(t)
        self._estimates.append(est)
        c = self.config
        names = (c.distance_channel, c.direction_channel, c.depth_channel)
        if all(n in batch.channels for n in names):
            self._labels.append({n: np.asarray(batch.channels[n], float).reshape(len(batch))
                                 for n in names})
        return est

    def on_movement_end(self, result: MovementResult) -> None:
        # Each exploratory movement is a trial of its own: a closed loop's clock runs on
        # without a gap, so the next window must not read this movement's forces.
        self._buffer = None

    def _windows(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        w = self.model.settings.window_steps
        if self._buffer is None:
            self._buffer = np.repeat(x[:1], w - 1, axis=0)
        joined = np.concatenate([self._buffer, x])
        self._buffer = joined[len(joined) - (w - 1):]
        index = np.arange(w)[None, :] + np.arange(len(x))[:, None]
        out: NDArray[np.float64] = joined[index]
        return out

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        est = self.estimate(batch)
        near = est.near_probability(self.config.near_mm)
        return ClassProbabilities(np.asarray(batch.timestamps_s, dtype=np.float64),
                                  np.column_stack([1.0 - near, near]), self.classes)

    @property
    def estimates(self) -> tuple[NDArray[np.float64], ObjectEstimate]:
        """Times and estimates of every sample since the last reset."""
        if not self._estimates:
            return np.empty(0), ObjectEstimate(np.empty(0), np.empty(0), np.empty((0, 3)),
                                               np.empty((0, 2)))
        if len(self._estimates) > 1:  # joined once, so that lookups stay linear in a run
            e = self._estimates
            self._estimates = [ObjectEstimate(
                np.concatenate([x.distance_mm for x in e]),
                np.concatenate([x.distance_std_mm for x in e]),
                np.concatenate([x.direction_proba for x in e]),
                np.concatenate([x.depth_proba for x in e]))]
            self._times = [np.concatenate(self._times)]
        return self._times[0], self._estimates[0]

    def estimate_at(self, times_s: NDArray[np.float64]) -> ObjectEstimate:
        """The estimates made at ``times_s`` (rows NaN where none was made at that time).

        A sensor model reads them for the located measurements this classifier's output
        became (``distance-estimate``).
        """
        times = np.asarray(times_s, dtype=np.float64)
        if self._times and len(times) and np.all(np.isin(times, self._times[-1])):
            t, est = self._times[-1], self._estimates[-1]  # the latest update: the usual case
        else:
            t, est = self.estimates
        n = len(times)
        out = ObjectEstimate(np.full(n, np.nan), np.full(n, np.nan), np.zeros((n, 3)),
                             np.zeros((n, 2)))
        if not len(t) or not n:
            return out
        index = np.clip(np.searchsorted(t, times), 0, len(t) - 1)
        hit = np.abs(t[index] - times) <= 1e-9
        out.distance_mm[hit] = est.distance_mm[index[hit]]
        out.distance_std_mm[hit] = est.distance_std_mm[index[hit]]
        out.direction_proba[hit] = est.direction_proba[index[hit]]
        out.depth_proba[hit] = est.depth_proba[index[hit]]
        return out

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``estimates.npz`` (and a figure); metrics against labels streamed with it."""
        t, est = self.estimates
        if not len(t):
            return {}
        arrays = {"timestamps_s": t, "distance_mm": est.distance_mm,
                  "distance_std_mm": est.distance_std_mm,
                  "direction_proba": est.direction_proba, "depth_proba": est.depth_proba}
        metrics: dict[str, Any] = {f"{self.id}_replaced_samples": self.replaced_samples}
        if self._labels and sum(len(x[self.config.distance_channel]) for x in self._labels
                                ) == len(t):
            c = self.config
            truth = {n: np.concatenate([x[n] for x in self._labels])
                     for n in (c.distance_channel, c.direction_channel, c.depth_channel)}
            arrays |= {f"true_{n}": v for n, v in truth.items()}
            metrics |= {
                f"{self.id}_distance_mae_mm": float(np.mean(np.abs(
                    est.distance_mm - truth[c.distance_channel]))),
                f"{self.id}_direction_accuracy": float(np.mean(
                    est.direction_proba.argmax(1) == truth[c.direction_channel])),
                f"{self.id}_depth_accuracy": float(np.mean(
                    est.depth_proba.argmax(1) == truth[c.depth_channel])),
            }
        np.savez_compressed(outcome.out_dir / "estimates.npz", **arrays)  # type: ignore[arg-type]
        if outcome.figures:
            from ._figures import save_estimate_figure

            c = self.config
            save_estimate_figure(outcome.out_dir / f"{self.id}-estimates.png", t, est,
                                 arrays.get(f"true_{c.distance_channel}"),
                                 arrays.get(f"true_{c.direction_channel}"),
                                 arrays.get(f"true_{c.depth_channel}"))
        (outcome.out_dir / f"{self.id}-model.json").write_text(json.dumps(
            {"settings": self.model.settings.__dict__}, indent=2) + "\n")
        return metrics
