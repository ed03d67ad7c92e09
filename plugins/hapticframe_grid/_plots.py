"""Figures of the occupancy grid (matplotlib's Agg canvas; imported only at finalize)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import Region

__all__ = ["save_log_odds_figure"]


def save_log_odds_figure(
    path: Path,
    region: Region,
    cell_size_m: float,
    log_odds: NDArray[np.float64],
    limits: tuple[float, float],
    *,
    title: str,
    outlines: Sequence[NDArray[np.float64]] = (),
) -> Path:
    """Draw ``log_odds`` (``(nx, ny)``, x-major) with the true outlines in red; save as PNG."""
    # An explicit Agg canvas leaves pyplot's global backend untouched.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure

    path.parent.mkdir(parents=True, exist_ok=True)
    figure = Figure(figsize=(7.0, 5.0), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot(1, 1, 1)
    nx, ny = log_odds.shape
    extent = (
        region.x_min_m,
        region.x_min_m + nx * cell_size_m,
        region.y_min_m,
        region.y_min_m + ny * cell_size_m,
    )
    image = axes.imshow(
        log_odds.T,
        origin="lower",
        extent=extent,
        # White is "unknown" (log odds 0) whatever the asymmetric clamping bounds.
        norm=TwoSlopeNorm(vmin=min(limits[0], -1e-9), vcenter=0.0, vmax=max(limits[1], 1e-9)),
        cmap="RdBu_r",
        interpolation="nearest",
        aspect="equal",
    )
    figure.colorbar(image, ax=axes, label="log odds of occupancy", shrink=0.85)
    for outline in outlines:
        closed = np.vstack([outline, outline[:1]])
        axes.plot(closed[:, 0], closed[:, 1], color="black", linewidth=1.2)
    axes.set_xlim(region.x_min_m, region.x_max_m)
    axes.set_ylim(region.y_min_m, region.y_max_m)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    figure.savefig(path)
    return path
