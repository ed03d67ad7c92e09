"""Figures of the occupancy grid (matplotlib, imported on use)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hapticframe import plotting
from hapticframe.kinds import MovementResult, Region

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["draw_log_odds", "save_log_odds_figure"]


def draw_log_odds(
    region: Region,
    cell_size_m: float,
    log_odds: NDArray[np.float64],
    limits: tuple[float, float],
    *,
    title: str,
    outlines: Sequence[NDArray[np.float64]] = (),
    movements: Sequence[MovementResult] = (),
) -> Figure:
    """``log_odds`` (``(nx, ny)``, x-major) with the true outlines and the fingertip's
    movements; returns the laid-out Figure."""
    from matplotlib.colors import TwoSlopeNorm

    figure, axes, colorbar_axes = plotting.map_figure()
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
    )
    figure.colorbar(image, cax=colorbar_axes, label="log odds of occupancy")
    plotting.draw_outlines(axes, outlines, colour="black")
    plotting.draw_movements(axes, movements, colour="tab:purple")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    bounds = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
    plotting.layout_map(figure, axes, colorbar_axes, bounds)
    return figure


def save_log_odds_figure(
    path: Path,
    region: Region,
    cell_size_m: float,
    log_odds: NDArray[np.float64],
    limits: tuple[float, float],
    *,
    title: str,
    outlines: Sequence[NDArray[np.float64]] = (),
    movements: Sequence[MovementResult] = (),
) -> Path:
    """Draw :func:`draw_log_odds` and save it as PNG at ``path``."""
    figure = draw_log_odds(region, cell_size_m, log_odds, limits, title=title,
                           outlines=outlines, movements=movements)
    return plotting.save_figure(figure, path)
