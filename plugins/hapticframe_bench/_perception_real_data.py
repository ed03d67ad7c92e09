"""Features of real BioTac recordings (Penn BOLT) and of calibrated synthetic press trials.

Each recording (one fingertip of one trial) is zeroed on its first ``tare_frames`` frames,
which the fingertip spends at rest in open air (the biotac sensor's causal replay tare),
labelled frame by frame with the contact reference "derived from pdc"
(``hapticframe_biotac.derived_from_pdc``, on the raw counts), and turned into EMD tensors
once, in worker processes. Sparse codes depend on the dictionaries, which each training
source learns on its own training frames: :func:`code_trials` codes a list of trials with
a given coder, into copies.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._perception_data import FEATURE_CHANNELS, PerceptionData, TrialFeatures

__all__ = ["RecordingId", "code_trials", "fit_coder", "press_features", "real_features"]

FloatArray = NDArray[np.float64]
#: (object, trial, finger) of a real recording.
RecordingId = tuple[str, str, int]


def _featurise(frames: Any, reference: NDArray[np.int8], tare: int,
               emd_settings: dict[str, Any]) -> tuple[dict[str, FloatArray], NDArray[np.int64]]:
    from hapticframe.kinds import BuildContext
    from hapticframe_biotac import tare_frames
    from hapticframe_tactile_features import EMDFeatureExtractor, EMDFeaturesConfig

    batch = tare_frames(frames, tare).to_sample_batch()
    extractor = EMDFeatureExtractor(EMDFeaturesConfig(**emd_settings),
                                    BuildContext("emd", np.random.default_rng(0)))
    features = extractor.transform(batch)
    rows = np.searchsorted(frames.timestamps_s, features.timestamps_s)
    tensors = {m: np.asarray(features.channels[c], dtype=np.float64)
               for m, c in FEATURE_CHANNELS.items()}
    return tensors, reference[rows].astype(np.int64)


def _real_job(job: tuple[Any, ...]) -> tuple[int, dict[str, FloatArray], NDArray[np.int64], int]:
    from threadpoolctl import threadpool_limits

    from hapticframe_biotac import PdcReference, load_bolt

    position, path, trial, finger, reference, tare, emd_settings = job
    with threadpool_limits(limits=1):
        frames = load_bolt(path, [trial])[finger].frames
        labels = PdcReference(**reference)(frames.pdc)
        tensors, rows = _featurise(frames, labels, tare, emd_settings)
    return position, tensors, rows, len(frames)


def _press_job(job: tuple[Any, ...]) -> tuple[int, dict[str, FloatArray], NDArray[np.int64], int]:
    from threadpoolctl import threadpool_limits

    from hapticframe_biotac import PdcReference, generate_press_trial

    position, calibration, seed, reference, tare, emd_settings = job
    with threadpool_limits(limits=1):
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 17, int(position)]))
        frames = generate_press_trial(calibration, rng)
        labels = PdcReference(**reference)(frames.pdc)
        tensors, rows = _featurise(frames, labels, tare, emd_settings)
    return position, tensors, rows, len(frames)


def _map(function: Callable[[Any], Any], jobs: list[Any], workers: int,
         say: Callable[[str], None], what: str) -> list[Any]:
    every = max(1, len(jobs) // 5)
    started = time.perf_counter()
    out: list[Any] = []

    def progress() -> None:
        if len(out) % every == 0 and len(out) < len(jobs):
            say(f"{what}: {len(out)}/{len(jobs)} recordings, "
                f"{time.perf_counter() - started:.0f} s")

    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            out.append(function(job))
            progress()
    else:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
            for result in pool.map(function, jobs):
                out.append(result)
                progress()
    return sorted(out, key=lambda r: r[0])


def real_features(
    recordings: Sequence[tuple[str, str, str, int]], reference: dict[str, Any], tare: int,
    workers: int, emd_settings: dict[str, Any], say: Callable[[str], None],
) -> list[TrialFeatures]:
    """EMD tensors and reference labels of real recordings ``(path, object, trial, finger)``;
    ``TrialFeatures.medium`` holds the object, ``split`` is ``"real"``."""
    jobs = [(i, path, trial, finger, reference, tare, emd_settings)
            for i, (path, _obj, trial, finger) in enumerate(recordings)]
    results = _map(_real_job, jobs, workers, say, "real features")
    return [TrialFeatures(index=i, medium=recordings[i][1], has_object=bool(labels.any()),
                          split="real", labels=labels, tensors=tensors, raw_frames=n)
            for i, tensors, labels, n in results]


def press_features(
    calibration: Any, n_trials: int, seed: int, reference: dict[str, Any], tare: int,
    workers: int, emd_settings: dict[str, Any], say: Callable[[str], None],
) -> list[TrialFeatures]:
    """EMD tensors and reference labels of ``n_trials`` synthetic press trials generated
    from ``calibration`` (``hapticframe_biotac.generate_press_trial``), split 80/20 into
    ``"train"`` and ``"validation"``."""
    jobs = [(i, calibration, seed, reference, tare, emd_settings) for i in range(n_trials)]
    results = _map(_press_job, jobs, workers, say, "calibrated synthetic features")
    n_val = max(1, round(0.2 * n_trials)) if n_trials >= 2 else 0
    return [TrialFeatures(index=i, medium="press", has_object=bool(labels.any()),
                          split="validation" if i < n_val else "train", labels=labels,
                          tensors=tensors, raw_frames=n)
            for i, tensors, labels, n in results]


def fit_coder(trials: Sequence[TrialFeatures], settings: dict[str, Any], fit_frames: int,
              seed: int) -> Any:
    """A sparse coder whose dictionaries are learned on ``fit_frames`` frames drawn from
    ``trials``."""
    from hapticframe.kinds import BuildContext, SampleBatch
    from hapticframe_tactile_features import SparseCodingConfig, SparseCodingExtractor

    coder = SparseCodingExtractor(
        SparseCodingConfig(**settings),
        BuildContext("sparse-coding", np.random.default_rng(np.random.SeedSequence([seed, 11]))))
    stacked = {m: np.concatenate([t.tensors[m] for t in trials]) for m in FEATURE_CHANNELS}
    n_rows = next(iter(stacked.values())).shape[0]
    pick = np.random.default_rng(np.random.SeedSequence([seed, 13]))
    chosen = np.sort(pick.choice(n_rows, size=min(n_rows, fit_frames), replace=False))
    coder.fit([SampleBatch(np.arange(chosen.size, dtype=np.float64) * 0.01,
                           {FEATURE_CHANNELS[m]: v[chosen] for m, v in stacked.items()})])
    return coder


def code_trials(trials: Sequence[TrialFeatures], coder: Any,
                split: Callable[[TrialFeatures], str] | None = None) -> list[TrialFeatures]:
    """Copies of ``trials`` with ``coder``'s codes (and amplitudes), ``split`` re-assigned."""
    from hapticframe.kinds import SampleBatch

    out = []
    for t in trials:
        batch = SampleBatch(np.arange(len(t), dtype=np.float64) * 0.01,
                            {FEATURE_CHANNELS[m]: v for m, v in t.tensors.items()})
        coded = coder.update(batch)
        out.append(dataclasses.replace(
            t, split=t.split if split is None else split(t),
            codes={m: np.asarray(coded.channels[f"{m}_code"], dtype=np.float64)
                   for m in FEATURE_CHANNELS},
            amplitudes={m: np.asarray(coded.channels[f"{m}_amplitude"], dtype=np.float64)
                        for m in FEATURE_CHANNELS if f"{m}_amplitude" in coded.channels}))
    return out


def as_data(trials: list[TrialFeatures], coder: Any, tare: int) -> PerceptionData:
    """A :class:`PerceptionData` for the architectures' trainer (splits as the trials say)."""
    return PerceptionData(trials=trials, timing_s={}, tare_frames=tare,
                          tare_source="trial_start", coder=coder)
