"""The paper's metrics on the test trials, for the authors' models and ours alike.

The authors' ``test_main.py`` slides a 5-step window over each test trial and scores the
prediction at the window's last step against that step's label. :func:`score_trials` does
the same for any estimator that gives per-step estimates: every step from the 5th to the
last, per trial, direction and depth accuracy and the distance's mean absolute error (mm);
and the estimate at the trial's last step (the tool at the object, where the authors'
direction and depth models were trained: their ``truncated`` tables).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._data import RakingTrial, select_inputs, windows
from ._keras import KerasSequential, load_keras_model
from ._model import ObjectEstimate, RakingModel

__all__ = ["AUTHORS_WINDOW", "AuthorsModels", "TrialScores", "authors_models_dir",
           "score_trials", "summarize"]

#: The authors' window: 5 steps.
AUTHORS_WINDOW = 5


@dataclass(frozen=True)
class TrialScores:
    """Per-trial scores (arrays over trials)."""

    names: tuple[str, ...]
    direction_accuracy: NDArray[np.float64]
    depth_accuracy: NDArray[np.float64]
    distance_mae_mm: NDArray[np.float64]
    final_direction_correct: NDArray[np.float64]
    final_depth_correct: NDArray[np.float64]
    final_distance_error_mm: NDArray[np.float64]


def authors_models_dir() -> Path:
    """The authors' trained models as shipped (``data/authors_models``)."""
    return Path(str(resources.files("hapticframe_raking") / "data" / "authors_models"))


@dataclass(frozen=True)
class AuthorsModels:
    """The authors' three models for one input set."""

    input_set: str
    direction: KerasSequential
    depth: KerasSequential
    distance: KerasSequential

    @classmethod
    def load(cls, input_set: str, directory: str | Path | None = None) -> AuthorsModels:
        d = Path(directory) if directory is not None else authors_models_dir()
        return cls(input_set, *(load_keras_model(d / f"{input_set}_{task}_model.h5")
                                for task in ("direction", "depth", "distance")))

    def estimate_trial(self, inputs: NDArray[np.float64]) -> ObjectEstimate:
        """Per step from the 5th: each window's last-step outputs (as test_main.py)."""
        x = windows(inputs, AUTHORS_WINDOW, pad=False)
        direction = self.direction(x)[:, -1]
        deep = self.depth(x)[:, -1, 0]
        distance = self.distance(x)[:, -1, 0]
        return ObjectEstimate(distance, np.full_like(distance, np.nan), direction,
                              np.stack([1.0 - deep, deep], axis=1))


def score_trials(estimate: Callable[[NDArray[np.float64]], ObjectEstimate],
                 trials: Sequence[RakingTrial], input_set: str, *,
                 first_step: int = AUTHORS_WINDOW) -> TrialScores:
    """Score per-step estimates from step ``first_step`` (1-based) to each trial's end.

    ``estimate`` maps a trial's inputs ``(n, d)`` to estimates at its steps: ``n`` of them
    (a streaming estimator) or ``n - first_step + 1`` (the authors' windows).
    """
    rows = []
    for trial in trials:
        est = estimate(select_inputs(trial.force, input_set))
        n = len(trial)
        skip = len(est.distance_mm) - (n - first_step + 1)
        if skip < 0:
            raise ValueError(f"trial {trial.name}: {len(est.distance_mm)} estimates for "
                             f"{n} steps")
        direction = est.direction_proba[skip:].argmax(axis=1)
        depth = est.depth_proba[skip:].argmax(axis=1)
        distance = est.distance_mm[skip:]
        s = slice(first_step - 1, None)
        rows.append((
            np.mean(direction == trial.direction[s]), np.mean(depth == trial.depth[s]),
            np.mean(np.abs(distance - trial.distance_mm[s])),
            float(direction[-1] == trial.direction[-1]), float(depth[-1] == trial.depth[-1]),
            abs(float(distance[-1] - trial.distance_mm[-1]))))
    cols = np.array(rows, dtype=np.float64).T
    return TrialScores(tuple(t.name for t in trials), *cols)


def summarize(scores: TrialScores) -> dict[str, dict[str, float]]:
    """Mean, standard deviation, median, min and max over trials of each score."""
    out = {}
    for key in ("direction_accuracy", "depth_accuracy", "distance_mae_mm",
                "final_direction_correct", "final_depth_correct", "final_distance_error_mm"):
        v = getattr(scores, key)
        out[key] = {"mean": float(v.mean()), "std": float(v.std()),
                    "median": float(np.median(v)), "min": float(v.min()),
                    "max": float(v.max())}
    return out


def model_estimator(model: RakingModel) -> Callable[[NDArray[np.float64]], ObjectEstimate]:
    """``model`` as the per-trial estimate :func:`score_trials` takes."""
    return model.estimate_trial
