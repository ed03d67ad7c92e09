"""Figures of the GP occupancy map: mean and standard deviation (matplotlib, imported on use).

Both maps show the true objects (when the scene has them) and the fingertip's movements; the
mean also shows the estimated outline at the run's outline level.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hapticframe import plotting
from hapticframe.kinds import OUTLINE_LEVEL, MovementResult, Region

__all__ = ["save_map_figures"]

FloatArray = NDArray[np.float64]


def save_map_figures(
    out_dir: Path,
    region: Region,
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    std: FloatArray,
    *,
    outlines: Sequence[FloatArray] = (),
    movements: Sequence[MovementResult] = (),
    outline_level: float = OUTLINE_LEVEL,
    method: str = "",
) -> list[Path]:
    """Write ``gp_mean.png`` and ``gp_std.png``; return the paths."""
    how = f" ({method})" if method else ""
    mean_figure = plotting.draw_occupancy_map(
        region, xs, ys, mean, title=f"GP occupancy mean{how}", label="p(occupied)",
        vmax=1.0, outlines=outlines, movements=movements, outline_level=outline_level)
    std_figure = plotting.draw_occupancy_map(
        region, xs, ys, std, title=f"GP occupancy standard deviation{how}",
        label="std of p(occupied)", vmax=max(float(std.max()), 1e-12), outlines=outlines,
        movements=movements)
    return [plotting.save_figure(mean_figure, out_dir / "gp_mean.png"),
            plotting.save_figure(std_figure, out_dir / "gp_std.png")]
