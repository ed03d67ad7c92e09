"""Linear separability of the synthetic BioTac frames (a check on the perception dataset).

The perception benchmark trains on the synthetic trials of ``hapticframe_biotac``; they
are only a fair test if a linear classifier on the raw counts cannot already read contact
from every frame. :func:`linear_svm_separability` measures that (``docs/synthetic-biotac.md``:
it must stay at or below 90 %, yet well above chance). scikit-learn is imported when it runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hapticframe_biotac import frame_features

__all__ = ["linear_svm_separability"]


def linear_svm_separability(
    trials: list[Any], rng: np.random.Generator, test_fraction: float = 0.3
) -> dict[str, float]:
    """Frame-wise linear SVM on raw features, split by trial (scikit-learn imported here).

    Trials with and without the object are split separately so both sides hold both kinds.
    Features are standardised with the training frames' mean and spread; the SVM weights
    classes by their frequency (the thesis oversampled the minority class instead).

    Parameters
    ----------
    trials : list of hapticframe_biotac.Trial
        Generated trials (:func:`hapticframe_biotac.generate_trial`).
    rng : numpy.random.Generator
        Draws the split.
    test_fraction : float
        Share of each kind of trial (with and without the object) held out, in (0, 1).

    Returns
    -------
    dict
        ``accuracy``, ``balanced_accuracy``, ``majority_accuracy`` (of always answering
        "free" on the test frames) and the numbers of trials and frames on each side.
    """
    from sklearn.svm import LinearSVC

    if not 0.0 < test_fraction < 1.0:
        raise ValueError("test_fraction must lie in (0, 1)")
    test_ids: list[int] = []
    for kind in (True, False):
        ids = [i for i, tr in enumerate(trials) if tr.spec.has_object is kind]
        ids = [ids[j] for j in rng.permutation(len(ids))]
        test_ids += ids[: max(1, round(test_fraction * len(ids)))] if ids else []
    test_set = set(test_ids)
    train = [tr for i, tr in enumerate(trials) if i not in test_set]
    test = [trials[i] for i in sorted(test_set)]
    if not train or not test:
        raise ValueError("need at least one trial on each side of the split")
    x_train = np.vstack([frame_features(tr) for tr in train])
    y_train = np.concatenate([tr.contact for tr in train])
    x_test = np.vstack([frame_features(tr) for tr in test])
    y_test = np.concatenate([tr.contact for tr in test])
    if np.unique(y_train).size < 2:
        raise ValueError("the training trials hold only one class")
    mean = x_train.mean(axis=0)
    spread = x_train.std(axis=0)
    spread[spread == 0.0] = 1.0
    model = LinearSVC(C=1.0, class_weight="balanced", dual=False, max_iter=5000)
    model.fit((x_train - mean) / spread, y_train)
    predicted = model.predict((x_test - mean) / spread)
    recalls = [np.mean(predicted[y_test == c] == c) for c in (0, 1) if np.any(y_test == c)]
    return {
        "accuracy": float(np.mean(predicted == y_test)),
        "balanced_accuracy": float(np.mean(recalls)),
        "majority_accuracy": float(np.mean(y_test == 0)),
        "n_train_trials": float(len(train)),
        "n_test_trials": float(len(test)),
        "n_train_frames": float(y_train.size),
        "n_test_frames": float(y_test.size),
    }
