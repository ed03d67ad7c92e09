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
    verdict: str = "",
) -> Figure:
    """``log_odds`` (``(nx, ny)``, x-major) with the true outlines and the fingertip's
    movements, on a linear colour scale symmetric about 0 (white: unknown), with a note of
    what the map is and ``verdict`` (:func:`hapticframe.plotting.draw_verdict`); returns the
    laid-out Figure."""
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
        # One linear scale symmetric about 0, so white is "unknown" and equal distances
        # from white are equal evidence, whatever the asymmetric clamping bounds.
        vmin=-_symmetric_limit(limits),
        vmax=_symmetric_limit(limits),
        cmap="RdBu_r",
        interpolation="nearest",
    )
    figure.colorbar(image, cax=colorbar_axes, label="log odds of occupancy")
    plotting.draw_outlines(axes, outlines, colour="black")
    plotting.draw_movements(axes, movements, colour="tab:purple")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    plotting.draw_verdict(axes, verdict)
    bounds = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
    plotting.layout_map(figure, axes, colorbar_axes, bounds,
                        note=_NOTE.format(cell_cm=100 * cell_size_m))
    return figure


# What a reader of the figure needs and cannot see in it. The pattern it explains was
# measured on the README's main job (tests/plugins/test_grid.py checks it): along the
# phase-1 line every other cell holds 5 observed points against 2 and ends at log odds
# -2.0 against -0.8.
_NOTE = ("Map 'grid': an occupancy grid of {cell_cm:g} cm cells (OctoMap-style log odds, the "
         "thesis's baseline map), beside the Bayesian\nHilbert Map and fed by its input sensor "
         "model: each observed point adds its log odds to its cell (red occupied, blue free,\n"
         "white unknown). The regular darker squares along a path are sampling, not sand: a "
         "sample is mapped as a polar\ngrid of points ahead of the fingertip (failure-zone "
         "kernel defaults: 1.5 cm apart, a sample per 2 cm of travel), a few\non the path "
         "itself, so every other cell on a path holds about 2.5 times the points of its "
         "neighbours (the\nfingertip's own point and those of the samples behind it), so "
         "more free evidence.")


def _symmetric_limit(limits: tuple[float, float]) -> float:
    """The larger clamping bound in magnitude (at least 1e-9)."""
    return max(abs(float(limits[0])), abs(float(limits[1])), 1e-9)


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
    verdict: str = "",
) -> Path:
    """Draw :func:`draw_log_odds` and save it as PNG at ``path``."""
    figure = draw_log_odds(region, cell_size_m, log_odds, limits, title=title,
                           outlines=outlines, movements=movements, verdict=verdict)
    return plotting.save_figure(figure, path)
