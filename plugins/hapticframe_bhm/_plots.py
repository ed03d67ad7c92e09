"""Figures of the BHM (matplotlib's Agg canvas; imported only when a run finalizes)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import Region

__all__ = ["save_map_figures"]

FloatArray = NDArray[np.float64]


def _draw(
    path: Path,
    region: Region,
    xs: FloatArray,
    ys: FloatArray,
    values: FloatArray,
    *,
    title: str,
    label: str,
    vmax: float | None,
    outlines: Sequence[FloatArray] = (),
    interaction_hinges: FloatArray | None = None,
    contour_level: float | None = None,
) -> None:
    # The object-oriented API with an explicit Agg canvas leaves pyplot's global backend
    # (and any interactive session) untouched.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 5.0), dpi=120)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot(1, 1, 1)
    extent = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
    image = axes.imshow(
        values, origin="lower", extent=extent, vmin=0.0, vmax=vmax, cmap="viridis", aspect="equal"
    )
    figure.colorbar(image, ax=axes, label=label, shrink=0.85)
    if contour_level is not None and values.min() < contour_level < values.max():
        axes.contour(xs, ys, values, levels=[contour_level], colors="white", linewidths=1.0)
    for outline in outlines:
        closed = np.vstack([outline, outline[:1]])
        axes.plot(closed[:, 0], closed[:, 1], color="red", linewidth=1.2)
    if interaction_hinges is not None and len(interaction_hinges):
        axes.plot(
            interaction_hinges[:, 0],
            interaction_hinges[:, 1],
            linestyle="none",
            marker="+",
            markersize=4,
            color="orange",
        )
    axes.set_xlim(region.x_min_m, region.x_max_m)
    axes.set_ylim(region.y_min_m, region.y_max_m)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    figure.savefig(path)


def save_map_figures(
    out_dir: Path,
    region: Region,
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    std: FloatArray,
    *,
    outlines: Sequence[FloatArray] = (),
    interaction_hinges: FloatArray | None = None,
) -> list[Path]:
    """Write ``bhm_mean.png`` (with true outlines, red) and ``bhm_std.png``; return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    mean_path = out_dir / "bhm_mean.png"
    std_path = out_dir / "bhm_std.png"
    _draw(
        mean_path,
        region,
        xs,
        ys,
        mean,
        title="BHM occupancy (red: truth, white: p = 0.5, +: interaction hinges)",
        label="p(occupied)",
        vmax=1.0,
        outlines=outlines,
        interaction_hinges=interaction_hinges,
        contour_level=0.5,
    )
    _draw(
        std_path,
        region,
        xs,
        ys,
        std,
        title="BHM occupancy standard deviation",
        label="std of p(occupied)",
        vmax=max(float(std.max()), 1e-12),
    )
    return [mean_path, std_path]
