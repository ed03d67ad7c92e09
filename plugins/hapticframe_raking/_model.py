"""The multi-head raking estimator: one LSTM over a short window, three heads.

From the last ``window_steps`` samples of the chosen tactile inputs, one LSTM layer and one
dense layer give, per step, the distance to the object as a Laplace distribution (location
and scale: the loss is its negative log-likelihood, so the mean absolute error the paper
scores is what the location minimises, and the scale is the uncertainty), the direction
class probabilities (3) and the depth class probabilities (2). One network rather than the
authors' three: the heads share what the window says about the sand ahead.

Training uses torch (the ``learn`` extra), seeded by a generator passed in; the trained
weights are plain numpy arrays run by :class:`~hapticframe_raking.LSTMLayer` (no torch at
run time), saved as ``weights.npz`` and ``model.json``.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.artifacts import read_json_object
from hapticframe.bounded_io import open_regular, read_npz

from ._data import INPUT_SETS, windows
from ._lstm import DenseLayer, LSTMLayer, softmax

__all__ = ["EstimatorSettings", "ObjectEstimate", "RakingModel", "TrainingTrial", "fit_model"]

FloatArray = NDArray[np.float64]
#: Distances are learned in units of this (keeps the regression target near 1).
DISTANCE_SCALE_MM = 100.0
#: Bounds on the log of the Laplace scale (in DISTANCE_SCALE_MM units): 0.25 mm .. 2 m.
_LOG_SCALE_MIN, _LOG_SCALE_MAX = math.log(0.0025), math.log(20.0)
#: Bytes of weights a saved estimator may declare (ours hold well under 1 MB).
_MAX_WEIGHT_BYTES = 64 * 1024**2
_HEADS = 1 + 1 + 3 + 2  # location, log scale, direction logits, depth logits


@dataclass(frozen=True)
class EstimatorSettings:
    """How the estimator is built and trained (the plugin's config carries the same)."""

    input_set: str = "4_3-axis"
    window_steps: int = 10
    hidden_units: int = 32
    epochs: int = 15
    batch_size: int = 128
    learning_rate: float = 3e-3
    skip_first_steps: int = 20
    #: Distances beyond this are learned as this (mm; None: not capped). Far from the object
    #: the forces do not tell the distance, and an uncapped model learns the training
    #: trials' start distances instead; the map reads no estimate beyond 0.1 m anyway.
    range_mm: float | None = None

    def __post_init__(self) -> None:
        if self.input_set not in INPUT_SETS:
            raise ValueError(f"input_set {self.input_set!r} is not one of {', '.join(INPUT_SETS)}")
        if self.range_mm is not None and not (math.isfinite(self.range_mm)
                                              and self.range_mm > 0):
            raise ValueError(f"range_mm must be a positive number or None, got {self.range_mm}")


@dataclass(frozen=True)
class TrainingTrial:
    """Inputs ``(n, d)`` of one trial with its per-step labels."""

    inputs: FloatArray
    distance_mm: FloatArray
    direction: NDArray[np.int64]
    depth: NDArray[np.int64]


@dataclass(frozen=True)
class ObjectEstimate:
    """Per step: distance (mm) with its standard deviation, direction and depth probabilities."""

    distance_mm: FloatArray
    distance_std_mm: FloatArray
    direction_proba: FloatArray
    depth_proba: FloatArray

    def near_probability(self, near_mm: float) -> FloatArray:
        """P(distance < near_mm) under each step's Laplace distribution."""
        b = self.distance_std_mm / math.sqrt(2.0)
        z = (near_mm - self.distance_mm) / b
        below = 0.5 * np.exp(-np.abs(np.minimum(z, 0.0)))  # z < 0: the lower tail
        above = 1.0 - 0.5 * np.exp(-np.maximum(z, 0.0))
        out: FloatArray = np.where(z < 0.0, below, above)
        return out


@dataclass(frozen=True)
class RakingModel:
    """A trained estimator: input standardisation, the LSTM and the heads (numpy)."""

    settings: EstimatorSettings
    mean: FloatArray
    std: FloatArray
    lstm: LSTMLayer
    head: DenseLayer

    def estimate_windows(self, x: FloatArray) -> ObjectEstimate:
        """Estimates for windows ``(m, window_steps, d)`` (raw inputs, not standardised)."""
        hidden = self.lstm.sequence((x - self.mean) / self.std)[:, -1]
        out = self.head(hidden)
        log_scale = np.clip(out[:, 1], _LOG_SCALE_MIN, _LOG_SCALE_MAX)
        return ObjectEstimate(
            distance_mm=out[:, 0] * DISTANCE_SCALE_MM,
            distance_std_mm=math.sqrt(2.0) * np.exp(log_scale) * DISTANCE_SCALE_MM,
            direction_proba=softmax(out[:, 2:5]),
            depth_proba=softmax(out[:, 5:7]),
        )

    def estimate_trial(self, inputs: FloatArray) -> ObjectEstimate:
        """Estimates at every step of one trial ``(n, d)``, as streaming gives them."""
        return self.estimate_windows(windows(inputs, self.settings.window_steps, pad=True))

    def save(self, directory: str | Path) -> None:
        d = Path(directory)
        np.savez(d / "weights.npz", mean=self.mean, std=self.std, kernel=self.lstm.kernel,
                 recurrent=self.lstm.recurrent, bias=self.lstm.bias,
                 head_kernel=self.head.kernel, head_bias=self.head.bias)
        (d / "model.json").write_text(json.dumps(
            {"format": "hapticframe-raking-estimator", "version": 1,
             "settings": asdict(self.settings)}, indent=2) + "\n")

    @classmethod
    def load(cls, directory: str | Path) -> RakingModel:
        d = Path(directory)
        try:
            meta = read_json_object(d / "model.json")
            with open_regular(d / "weights.npz") as stream:
                raw = read_npz(stream, max_bytes=_MAX_WEIGHT_BYTES)
        except (OSError, ValueError) as exc:  # BoundedReadError is a ValueError
            raise ValueError(f"{d}: no saved raking estimator ({exc}); run hapticframe "
                             "train first") from None
        arrays = {}
        for key, value in raw.items():
            if value.dtype.kind not in "iuf" or not np.all(np.isfinite(value)):
                raise ValueError(f"{d}/weights.npz: {key!r} does not hold finite numbers")
            arrays[key] = np.asarray(value, dtype=np.float64)
        if meta.get("format") != "hapticframe-raking-estimator":
            raise ValueError(f"{d}/model.json is not a raking estimator's")
        try:
            settings = EstimatorSettings(**meta["settings"])
            model = cls(settings, arrays["mean"], arrays["std"],
                        LSTMLayer(arrays["kernel"], arrays["recurrent"], arrays["bias"]),
                        DenseLayer(arrays["head_kernel"], arrays["head_bias"]))
            width = len(INPUT_SETS[settings.input_set])
            fits = model.lstm.input_size == width and model.mean.shape == (width,) and (
                model.head.kernel.shape == (settings.hidden_units, _HEADS))
        except (KeyError, TypeError, IndexError, AttributeError, ValueError) as exc:
            raise ValueError(f"{d}: incomplete raking estimator ({type(exc).__name__}: "
                             f"{str(exc)[:200]})") from None
        if not fits:
            raise ValueError(f"{d}: weights do not fit input set {settings.input_set}")
        return model


def _training_arrays(trials: Sequence[TrainingTrial], settings: EstimatorSettings
                     ) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64]]:
    xs, ds, dirs, deps = [], [], [], []
    for trial in trials:
        w = windows(trial.inputs, settings.window_steps, pad=True)
        keep = slice(min(settings.skip_first_steps, max(len(w) - 1, 0)), None)
        xs.append(w[keep])
        d = trial.distance_mm[keep]
        ds.append(d if settings.range_mm is None else np.minimum(d, settings.range_mm))
        dirs.append(trial.direction[keep])
        deps.append(trial.depth[keep])
    return (np.concatenate(xs), np.concatenate(ds), np.concatenate(dirs),
            np.concatenate(deps))


def fit_model(trials: Sequence[TrainingTrial], settings: EstimatorSettings,
              rng: np.random.Generator, *, threads: int = 1) -> tuple[RakingModel, dict[str, Any]]:
    """Train the estimator on labelled trials; the model and a training report.

    ``rng`` seeds the initial weights and the batch order (no global random state is
    touched); ``threads`` caps torch's intra-op threads while training.
    """
    import torch

    if not trials:
        raise ValueError("no training trials")
    x, d, direction, depth = _training_arrays(trials, settings)
    if len(x) == 0:
        raise ValueError("the training trials hold no steps")
    bad = np.flatnonzero(~np.isfinite(x).all(axis=(1, 2)) | ~np.isfinite(d))
    if bad.size:
        raise ValueError(f"training window {int(bad[0])} holds NaN or infinity")
    if direction.min() < 0 or direction.max() > 2 or depth.min() < 0 or depth.max() > 1:
        raise ValueError("direction labels must be 0..2 and depth labels 0..1")
    flat = x.reshape(-1, x.shape[2])
    mean = flat.mean(axis=0)
    std = np.maximum(flat.std(axis=0), 1e-6)  # a constant input is centred, not divided by 0
    generator = torch.Generator().manual_seed(int(rng.integers(2**62)))
    previous = torch.get_num_threads()
    torch.set_num_threads(threads)
    started = time.perf_counter()
    try:
        lstm = torch.nn.LSTM(x.shape[2], settings.hidden_units, batch_first=True).double()
        head = torch.nn.Linear(settings.hidden_units, _HEADS).double()
        with torch.no_grad():
            for p in [*lstm.parameters(), *head.parameters()]:
                bound = 1.0 / math.sqrt(settings.hidden_units)
                p.copy_((torch.rand(p.shape, generator=generator, dtype=torch.float64) * 2 - 1)
                        * bound)
        params = [*lstm.parameters(), *head.parameters()]
        optimizer = torch.optim.Adam(params, lr=settings.learning_rate)
        xt = torch.from_numpy((x - mean) / std)
        dt = torch.from_numpy(d / DISTANCE_SCALE_MM)
        at, bt = torch.from_numpy(direction), torch.from_numpy(depth)
        losses = []
        for _ in range(settings.epochs):
            order = rng.permutation(len(x))
            total = 0.0
            for start in range(0, len(x), settings.batch_size):
                j = torch.from_numpy(order[start:start + settings.batch_size])
                hidden, _ = lstm(xt[j])
                out = head(hidden[:, -1])
                log_scale = out[:, 1].clamp(_LOG_SCALE_MIN, _LOG_SCALE_MAX)
                nll = (log_scale + (dt[j] - out[:, 0]).abs() / log_scale.exp()).mean()
                loss = (nll + torch.nn.functional.cross_entropy(out[:, 2:5], at[j])
                        + torch.nn.functional.cross_entropy(out[:, 5:7], bt[j]))
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                total += float(loss.detach()) * len(j)
            losses.append(total / len(x))
    finally:
        torch.set_num_threads(previous)
    state = {k: v.detach().numpy() for k, v in lstm.state_dict().items()}
    w_ih, w_hh = state["weight_ih_l0"], state["weight_hh_l0"]
    bias = state["bias_ih_l0"] + state["bias_hh_l0"]
    model = RakingModel(settings, mean, std, LSTMLayer(w_ih.T, w_hh.T, bias),
                        DenseLayer(head.weight.detach().numpy().T, head.bias.detach().numpy()))
    report = {"trials": len(trials), "windows": len(x), "epochs": settings.epochs,
              "final_loss": losses[-1], "losses": losses,
              "train_s": time.perf_counter() - started, "threads": threads,
              "settings": asdict(settings)}
    return model, report
