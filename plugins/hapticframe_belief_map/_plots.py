"""Figures: the contact-state timeline (Fig. 2.5d) and belief-map snapshots (Fig. 2.7).

matplotlib is imported only here, only at finalize, on an explicit Agg canvas that leaves
pyplot's global backend alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["save_belief_figure", "save_timeline_figure"]

FloatArray = NDArray[np.float64]


def _figure(width: float, height: float):  # type: ignore[no-untyped-def]
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), dpi=120)
    FigureCanvasAgg(figure)
    return figure


def save_timeline_figure(
    path: Path,
    timestamps_s: FloatArray,
    contact_probability: FloatArray,
    positions_m: FloatArray,
    first: int | None,
    last: int | None,
) -> Path:
    """Contact probability and decided state over time, first/last contact marked."""
    path.parent.mkdir(parents=True, exist_ok=True)
    figure = _figure(7.5, 5.0)
    top, bottom = figure.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    t = timestamps_s - (timestamps_s[0] if timestamps_s.size else 0.0)
    decided = (contact_probability > 0.5).astype(float)
    top.plot(t, contact_probability, color="tab:blue", linewidth=1.2, label="P(contact)")
    top.step(t, decided, where="post", color="tab:red", linewidth=1.0, label="decided state")
    top.axhline(0.5, color="grey", linewidth=0.6, linestyle=":")
    for index, name in ((first, "first contact"), (last, "last contact")):
        if index is not None:
            for axes in (top, bottom):
                axes.axvline(t[index], color="tab:orange", linestyle="--", linewidth=1.0)
            top.annotate(name, (t[index], 1.04), ha="center", fontsize=8, color="tab:orange",
                         annotation_clip=False)
    top.set_ylim(-0.05, 1.1)
    top.set_ylabel("contact probability")
    top.legend(loc="center left", fontsize=8)
    bottom.plot(t, positions_m[:, 0], label="x", color="black", linewidth=1.0)
    bottom.plot(t, positions_m[:, 1], label="y", color="grey", linewidth=1.0)
    bottom.set_ylabel("fingertip (m)")
    bottom.set_xlabel("time (s)")
    bottom.legend(loc="center left", fontsize=8)
    figure.suptitle("Fingertip contact state")
    figure.savefig(path)
    return path


def save_belief_figure(
    path: Path,
    xs: FloatArray,
    ys: FloatArray,
    mean: FloatArray,
    *,
    title: str,
    fingertip_m: FloatArray | None = None,
    outlines: Sequence[FloatArray] = (),
) -> Path:
    """``P(object)`` on the grid ``(ny, nx)`` in red-blue, the fingertip as a black marker."""
    from matplotlib.ticker import MaxNLocator

    path.parent.mkdir(parents=True, exist_ok=True)
    figure = _figure(6.5, 5.0)
    axes = figure.add_subplot(1, 1, 1)
    dx = (xs[1] - xs[0]) if xs.size > 1 else 1.0
    dy = (ys[1] - ys[0]) if ys.size > 1 else 1.0
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    image = axes.imshow(mean, origin="lower", extent=extent, vmin=0.0, vmax=1.0, cmap="RdBu_r",
                        interpolation="nearest", aspect="equal")
    figure.colorbar(image, ax=axes, label="P(object)", shrink=0.85)
    for outline in outlines:
        closed = np.vstack([outline, outline[:1]])
        axes.plot(closed[:, 0], closed[:, 1], color="black", linewidth=1.0)
    if fingertip_m is not None and np.all(np.isfinite(fingertip_m)):
        axes.plot(fingertip_m[0], fingertip_m[1], marker="o", color="black", markersize=6,
                  markerfacecolor="none", label="fingertip")
        axes.legend(loc="upper right", fontsize=8)
    axes.set_xlim(extent[0], extent[1])
    axes.set_ylim(extent[2], extent[3])
    # A narrow strip of a map would otherwise crowd its tick labels into each other.
    axes.xaxis.set_major_locator(MaxNLocator(nbins=5))
    axes.yaxis.set_major_locator(MaxNLocator(nbins=5))
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    figure.savefig(path)
    return path
