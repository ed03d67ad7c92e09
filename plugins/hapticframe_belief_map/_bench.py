"""Refit cost of the belief map (for ``hapticframe bench``; never asserted in tests).

The load imitates closed-loop exploration: straight raster sweeps across the thesis's
0.75 x 0.50 m region at 4 cm/s and 100 Hz (0.4 mm between observations), labelled by a
9.1 cm disc with 3 % label noise, fused in chunks of ``update_every`` observations.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, Observations

from ._belief_map import BeliefMap
from ._config import BeliefMapConfig

__all__ = ["raster_observations", "measure_refit_cost"]


def raster_observations(n: int, rng: np.random.Generator) -> Observations:
    """``n`` observations along horizontal sweeps 5 cm apart, object disc at (0.4, 0.25)."""
    step = 0.0004
    per_row = int(0.75 / step)
    index = np.arange(n)
    row = index // per_row
    along = (index % per_row) * step
    x = np.where(row % 2 == 0, along, 0.75 - along)
    y = 0.025 + 0.05 * (row % 10)
    points = np.column_stack([x, y]) + rng.normal(0.0, 0.0005, (n, 2))
    inside = np.hypot(points[:, 0] - 0.4, points[:, 1] - 0.25) < 0.0455
    flip = rng.random(n) < 0.03
    return Observations(points, np.where(inside ^ flip, 1.0, 0.0))


def measure_refit_cost(
    n_observations: int = 3000, repeats: int = 20, seed: int = 0, **config: Any
) -> dict[str, float]:
    """Median and p90 wall time of one refit after fusing ``n_observations`` (single thread).

    Returns the times in milliseconds, the number of points the SVC saw and the bin edge.
    """
    rng = np.random.default_rng(seed)
    cfg = BeliefMapConfig(**config)
    the_map = BeliefMap(cfg, BuildContext(id="bench", rng=np.random.default_rng(seed)))
    observations = raster_observations(n_observations, rng)
    started = time.perf_counter()
    the_map.update(observations)  # the first refit also imports scikit-learn
    first_update = time.perf_counter() - started
    durations = []
    for _ in range(repeats):
        started = time.perf_counter()
        the_map.refit()
        durations.append(time.perf_counter() - started)
    chunk = Observations(observations.points_m[: cfg.update_every], observations.targets[: cfg.update_every])
    update_durations = []
    for _ in range(repeats):
        started = time.perf_counter()
        the_map.update(chunk)  # binning plus one refit: the per-cadence cost
        update_durations.append(time.perf_counter() - started)
    ms = 1e3 * np.asarray(durations)
    update_ms = 1e3 * np.asarray(update_durations)
    return {
        "observations": float(n_observations),
        "representatives": float(the_map.representatives),
        "cell_size_m": the_map.cell_size_m,
        "refit_ms_median": float(np.median(ms)),
        "refit_ms_p90": float(np.percentile(ms, 90)),
        "update_ms_median": float(np.median(update_ms)),
        "first_update_ms": 1e3 * first_update,
    }
