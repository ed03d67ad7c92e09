"""Figures of the BHM: occupancy mean and standard deviation (matplotlib, imported on use).

Both maps show the true object (when the scene has one) and the fingertip's movements; the
mean also shows the estimated outline at the run's outline level and, when the map uses
region-dependent smoothing, the hinges switched to the interaction length scale.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import plotting
from hapticframe.kinds import OUTLINE_LEVEL, MovementResult, Region

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["draw_map", "save_kernel_figure", "save_map_figures"]

FloatArray = NDArray[np.float64]


def draw_map(
    region: Region,
    xs: FloatArray,
    ys: FloatArray,
    values: FloatArray,
    *,
    title: str,
    label: str,
    vmax: float,
    outlines: Sequence[FloatArray] = (),
    movements: Sequence[MovementResult] = (),
    interaction_hinges: FloatArray | None = None,
    outline_level: float | None = None,
    verdict: str = "",
) -> Figure:
    """One map ``values`` (``(len(ys), len(xs))``) with truth, path and, optionally, the
    ``outline_level`` curve and the interaction hinges; returns the laid-out Figure."""

    def hinges(axes: Axes) -> None:
        if interaction_hinges is not None and len(interaction_hinges):
            axes.plot(interaction_hinges[:, 0], interaction_hinges[:, 1], ls="none",
                      marker="+", ms=4, color="orange", label="interaction hinge")

    return plotting.draw_occupancy_map(
        region, xs, ys, values, title=title, label=label, vmax=vmax, outlines=outlines,
        movements=movements, outline_level=outline_level, extra=hinges, verdict=verdict)


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
    interaction_hinges: FloatArray | None = None,
    outline_level: float = OUTLINE_LEVEL,
    verdict: str = "",
) -> list[Path]:
    """Write ``bhm_mean.png`` and ``bhm_std.png`` (each saying ``verdict``); return the
    paths."""
    common: dict[str, Any] = {"outlines": outlines, "movements": movements, "verdict": verdict}
    mean_figure = draw_map(region, xs, ys, mean, title="BHM occupancy mean",
                           label="p(occupied)", vmax=1.0, interaction_hinges=interaction_hinges,
                           outline_level=outline_level, **common)
    std_figure = draw_map(region, xs, ys, std, title="BHM occupancy standard deviation",
                          label="std of p(occupied)", vmax=max(float(std.max()), 1e-12), **common)
    return [plotting.save_figure(mean_figure, out_dir / "bhm_mean.png"),
            plotting.save_figure(std_figure, out_dir / "bhm_std.png")]


def save_kernel_figure(
    path: Path,
    region: Region,
    hinges: FloatArray,
    length_scales: FloatArray,
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    *,
    outline_level: float = OUTLINE_LEVEL,
) -> Path:
    """``kernels.png``: every hinge coloured and sized by its learned length scale (as the
    thesis's Fig. 3.5c), over the ``outline_level`` curve of the occupancy mean."""
    figure, axes, colorbar_axes = plotting.map_figure()
    bounds = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
    scales_cm = 100.0 * np.asarray(length_scales, dtype=np.float64)
    sizes = 4.0 + 40.0 * (scales_cm / max(float(scales_cm.max()), 1e-12)) ** 2
    points = axes.scatter(hinges[:, 0], hinges[:, 1], c=scales_cm, s=sizes, cmap="viridis",
                          edgecolors="none")
    figure.colorbar(points, cax=colorbar_axes, label="length scale (cm)")
    plotting.draw_level_outline(axes, xs, ys, mean, outline_level,
                                label=f"estimated outline (p = {outline_level:g})")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title("BHM automorphing kernels")
    plotting.layout_map(figure, axes, colorbar_axes, bounds)
    return plotting.save_figure(figure, path)
