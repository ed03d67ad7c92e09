"""Latency of the streaming feature chain per 10 ms frame (a benchmark, not a test).

:func:`measure_chain_latency` streams synthetic BioTac-like frames one at a time through
``emd-features`` (all three modalities) and ``sparse-coding`` and times each frame from
the sensor values' arrival to the three sparse codes, on one thread (BLAS and OpenMP pools
limited with threadpoolctl), with the split per stage. The classifier step is not
included. Passing ``EMDFeaturesConfig(emd_backend="numpy")`` and
``SparseCodingConfig(encoder="sklearn")`` times the reference implementations in the
same way, for side-by-side figures.
"""

from __future__ import annotations

import os
import platform
import time
from contextlib import AbstractContextManager, nullcontext
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, SampleBatch

from ._config import EMDFeaturesConfig, SparseCodingConfig
from ._emd import _use_kernel, emd
from ._emd_features import EMDFeatureExtractor
from ._sparse import _use_numba
from ._sparse_coding import SparseCodingExtractor

__all__ = ["compare_emd_with_pyemd", "measure_chain_latency", "synthetic_biotac_frames"]


def synthetic_biotac_frames(
    n_frames: int, rng: np.random.Generator, *, frame_rate_hz: float = 100.0
) -> SampleBatch:
    """BioTac-shaped frames for timing: pac tones plus noise, drifting pdc and electrodes.

    Not the project's granular-media generator (``hapticframe_biotac``); it only has the
    layout and a realistic spread of frequencies, which is what the EMD cost depends on.
    """
    pac_rate = 22 * frame_rate_hz
    t_pac = np.arange(n_frames * 22) / pac_rate
    pac = (
        2048.0
        + 60.0 * np.sin(2 * np.pi * 180.0 * t_pac)
        + 40.0 * np.sin(2 * np.pi * 35.0 * t_pac + 0.4)
        + 25.0 * rng.standard_normal(t_pac.size)
    )
    walk = np.cumsum(rng.standard_normal(n_frames)) * 2.0
    pdc = 2000.0 + walk + 3.0 * rng.standard_normal(n_frames)
    electrodes = (
        3000.0
        + np.cumsum(rng.standard_normal((n_frames, 19)), axis=0)
        + 5.0 * rng.standard_normal((n_frames, 19))
    )
    times = (1 + np.arange(n_frames)) / frame_rate_hz
    return SampleBatch(
        times,
        {
            "pac": np.round(pac).reshape(n_frames, 22),
            "pdc": np.round(pdc),
            "electrodes": np.round(electrodes),
        },
    )


def _one_thread() -> AbstractContextManager[Any]:
    """Limit BLAS/OpenMP pools to one thread with threadpoolctl (scikit-learn depends on it).

    Without threadpoolctl nothing is limited here: set ``OMP_NUM_THREADS=1`` and
    ``OPENBLAS_NUM_THREADS=1`` (or ``MKL_NUM_THREADS=1``) before starting Python instead.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return nullcontext()
    return threadpool_limits(limits=1)


def measure_chain_latency(
    n_frames: int = 2000,
    *,
    seed: int = 0,
    fit_frames: int = 400,
    emd_config: EMDFeaturesConfig | None = None,
    coding_config: SparseCodingConfig | None = None,
) -> dict[str, Any]:
    """Median and p99 time per frame of the streaming ``emd-features`` → ``sparse-coding`` chain.

    Parameters
    ----------
    n_frames : int
        Frames timed (at least 2,000 for a p99 worth reporting); the first
        ``delay_frames`` produce no features and are timed too.
    seed : int
    fit_frames : int
        Frames whose features train the dictionaries first (0 keeps the random atoms);
        lasso cost depends on how well the dictionary fits the data.
    emd_config, coding_config : optional
        Defaults: the thesis's settings.

    Returns
    -------
    dict
        ``latency_ms_median``, ``latency_ms_p99``, ``latency_ms_max`` (wall clock);
        ``cpu_ms_median``, ``cpu_ms_p99`` (this thread's CPU time per frame: on a loaded
        machine the wall-clock tail holds time-slices given to other processes, the CPU
        time does not, so the two bracket the figure an idle machine would give); per stage
        ``emd_ms_median`` / ``emd_ms_p99`` (``emd-features.update``: ring buffers and the
        pac and pdc EMDs) and ``coding_ms_median`` / ``coding_ms_p99``
        (``sparse-coding.update``: three normalised lasso encodes); ``emd_backend`` and
        ``encoder`` (what ``"auto"`` resolved to), ``frames``, ``threads`` and ``machine``.

    Notes
    -----
    One thread: BLAS/OpenMP pools are limited to 1 with threadpoolctl (see
    :func:`_one_thread` for running without it); the numba kernels are serial. The
    compiled kernels are loaded (or compiled) before timing starts, by one untimed frame.
    """
    rng = np.random.default_rng(seed)
    emd_cfg = emd_config or EMDFeaturesConfig()
    code_cfg = coding_config or SparseCodingConfig()
    extractor = EMDFeatureExtractor(
        emd_cfg, BuildContext("latency-emd", np.random.default_rng(seed))
    )
    coder = SparseCodingExtractor(
        code_cfg, BuildContext("latency-codes", np.random.default_rng(seed + 1))
    )
    with _one_thread():
        if fit_frames > 0:
            coder.fit([extractor.transform(synthetic_biotac_frames(fit_frames, rng))])
        frames = synthetic_biotac_frames(n_frames, rng)
        # Load (or compile) the numba kernels outside the timed loop.
        coder.update(extractor.transform(synthetic_biotac_frames(emd_cfg.delay_frames + 1, rng)))
        extractor.reset()
        emd_ms = np.zeros(n_frames)
        total_ms = np.zeros(n_frames)
        cpu_ms = np.zeros(n_frames)
        for i in range(n_frames):
            frame = frames.select(slice(i, i + 1))
            cpu_start = time.thread_time()
            start = time.perf_counter()
            features = extractor.update(frame)
            middle = time.perf_counter()
            coder.update(features)
            end = time.perf_counter()
            cpu_ms[i] = 1e3 * (time.thread_time() - cpu_start)
            emd_ms[i] = 1e3 * (middle - start)
            total_ms[i] = 1e3 * (end - start)
    coding_ms = total_ms - emd_ms
    return {
        "latency_ms_median": float(np.median(total_ms)),
        "latency_ms_p99": float(np.percentile(total_ms, 99)),
        "latency_ms_max": float(total_ms.max()),
        "cpu_ms_median": float(np.median(cpu_ms)),
        "cpu_ms_p99": float(np.percentile(cpu_ms, 99)),
        "emd_ms_median": float(np.median(emd_ms)),
        "emd_ms_p99": float(np.percentile(emd_ms, 99)),
        "coding_ms_median": float(np.median(coding_ms)),
        "coding_ms_p99": float(np.percentile(coding_ms, 99)),
        "emd_backend": "numba" if _use_kernel(emd_cfg.emd_backend) else "numpy",
        "encoder": "numba" if _use_numba(code_cfg.encoder) else "sklearn",
        "frames": n_frames,
        "threads": 1,
        "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}",
    }


def compare_emd_with_pyemd(
    n_samples: int = 2200, *, repeats: int = 20, seed: int = 0
) -> dict[str, Any]:
    """Time :func:`emd` and PyEMD side by side on one pac-like signal (8 IMFs), one thread.

    Two pairings: each library with its own defaults, and both sifting exactly 10 times per
    IMF (``sd_threshold=0, max_sifts=10`` against ``EMD(FIXE=10)``), where they compute the
    same decomposition. Ours runs with ``backend="auto"`` (the numba kernel when installed;
    ``emd_numpy_ms_default`` times the numpy path too). PyEMD (PyPI ``EMD-signal``) is
    imported here only; it is a test and benchmark dependency. Figures are medians in
    milliseconds.
    """
    from PyEMD import EMD

    rng = np.random.default_rng(seed)
    t = np.arange(n_samples) / 2200.0
    x = (
        np.sin(2 * np.pi * 180.0 * t)
        + 0.6 * np.sin(2 * np.pi * 35.0 * t)
        + 0.1 * rng.standard_normal(n_samples)
    )

    def median_ms(call: Any) -> float:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            call()
            times.append(time.perf_counter() - start)
        return 1e3 * float(np.median(times))

    with _one_thread():
        emd(x[:64], 8)  # load (or compile) the numba kernel outside the timing
        ours_default = median_ms(lambda: emd(x, 8))
        ours_numpy = median_ms(lambda: emd(x, 8, backend="numpy"))
        theirs_default = median_ms(lambda: EMD().emd(x, max_imf=8))
        ours_fixed = median_ms(lambda: emd(x, 8, sd_threshold=0.0, max_sifts=10, residue_ratio=0.0))
        theirs_fixed = median_ms(
            lambda: EMD(FIXE=10, range_thr=0.0, total_power_thr=0.0).emd(x, max_imf=8)
        )
    return {
        "samples": n_samples,
        "emd_ms_default": ours_default,
        "pyemd_ms_default": theirs_default,
        "speedup_default": theirs_default / ours_default,
        "emd_backend": "numba" if _use_kernel("auto") else "numpy",
        "emd_numpy_ms_default": ours_numpy,
        "emd_ms_fixed10": ours_fixed,
        "pyemd_ms_fixed10": theirs_fixed,
        "speedup_fixed10": theirs_fixed / ours_fixed,
    }
