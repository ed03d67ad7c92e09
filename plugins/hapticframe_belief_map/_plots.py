"""Figures: the contact-state timeline (Fig. 2.5d) and belief-map snapshots (Fig. 2.7).

matplotlib is imported only at finalize, through :mod:`hapticframe.plotting`, on an explicit
Agg canvas that leaves pyplot's global backend alone. "Contact" in these figures is the
decided contact (contact probability above 0.5), not a labelled one.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from hapticframe import plotting
from hapticframe.kinds import OUTLINE_LEVEL

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["draw_belief", "draw_timeline", "save_belief_figure", "save_timeline_figure"]

FloatArray = NDArray[np.float64]


def draw_timeline(
    timestamps_s: FloatArray,
    contact_probability: FloatArray,
    positions_m: FloatArray,
    first: int | None,
    last: int | None,
) -> Figure:
    """Contact probability and decided state over time, the decided first and last contact
    marked; below, the fingertip's coordinates."""
    figure = plotting.new_figure(8.5, 5.0)
    figure.subplots_adjust(left=0.1, right=0.72, bottom=0.1, top=0.93, hspace=0.12)
    top, bottom = figure.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    t = timestamps_s - (timestamps_s[0] if timestamps_s.size else 0.0)
    decided = (contact_probability > 0.5).astype(float)
    top.plot(t, contact_probability, color="tab:blue", linewidth=1.2, label="P(contact)")
    top.step(t, decided, where="post", color="tab:red", linewidth=1.0, label="decided contact")
    top.axhline(0.5, color="grey", linewidth=0.6, linestyle=":", label="decision threshold")
    events = [(i, name) for i, name in ((first, "first"), (last, "last")) if i is not None]
    for number, (index, _) in enumerate(events):
        for axes in (top, bottom):
            axes.axvline(t[index], color="tab:orange", linestyle="--", linewidth=1.0,
                         label="decided first & last contact" if number == 0 and axes is top
                         else None)
    top.set_ylim(-0.05, 1.08)
    top.set_ylabel("contact probability")
    top.set_title("Fingertip contact state")
    top.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)
    bottom.plot(t, positions_m[:, 0], label="x", color="black", linewidth=1.0)
    bottom.plot(t, positions_m[:, 1], label="y", color="grey", linewidth=1.0)
    bottom.set_ylabel("fingertip (m)")
    bottom.set_xlabel("time (s)")
    bottom.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)
    return figure


def save_timeline_figure(
    path: Path,
    timestamps_s: FloatArray,
    contact_probability: FloatArray,
    positions_m: FloatArray,
    first: int | None,
    last: int | None,
) -> Path:
    """Write :func:`draw_timeline` as PNG at ``path``."""
    figure = draw_timeline(timestamps_s, contact_probability, positions_m, first, last)
    return plotting.save_figure(figure, path)


def draw_belief(
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    *,
    title: str,
    path_m: FloatArray | None = None,
    outlines: Sequence[FloatArray] = (),
    outline_level: float | None = OUTLINE_LEVEL,
) -> Figure:
    """``P(object)`` on the grid ``(ny, nx)`` in red-blue, the true outlines, the estimated
    outline at ``outline_level`` and the fingertip's path with a ring where it is."""
    figure, axes, colorbar_axes = plotting.map_figure()
    dx = (xs[1] - xs[0]) if xs.size > 1 else 1.0
    dy = (ys[1] - ys[0]) if ys.size > 1 else 1.0
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    image = axes.imshow(mean, origin="lower", extent=extent, vmin=0.0, vmax=1.0, cmap="RdBu_r",
                        interpolation="nearest")
    figure.colorbar(image, cax=colorbar_axes, label="P(object)")
    if outline_level is not None:
        plotting.draw_level_outline(axes, xs, ys, mean, outline_level, colour="black",
                                    label=f"estimated outline (P = {outline_level:g})")
    plotting.draw_outlines(axes, outlines)
    if path_m is not None:
        plotting.draw_path(axes, path_m)
    from matplotlib.ticker import MaxNLocator

    # A narrow strip of a map would otherwise crowd its tick labels into each other.
    axes.xaxis.set_major_locator(MaxNLocator(nbins=5))
    axes.yaxis.set_major_locator(MaxNLocator(nbins=5))
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    plotting.layout_map(figure, axes, colorbar_axes, extent)
    return figure


def save_belief_figure(
    path: Path,
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    *,
    title: str,
    path_m: FloatArray | None = None,
    outlines: Sequence[FloatArray] = (),
    outline_level: float | None = OUTLINE_LEVEL,
) -> Path:
    """Write :func:`draw_belief` as PNG at ``path``."""
    figure = draw_belief(xs, ys, mean, title=title, path_m=path_m, outlines=outlines,
                         outline_level=outline_level)
    return plotting.save_figure(figure, path)
