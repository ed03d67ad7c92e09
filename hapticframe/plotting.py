"""Shared drawing for the figures a run writes: one look, one layout, no clipping, cheap.

Every map figure of the bundled plugins (and of the core's scoring) is drawn the same way:
the map fills an axes box sized to the region's aspect, the colour bar sits beside it, the
legend below it, and the figure is exactly as large as these need, so nothing is clipped
and no layout engine runs (constrained layout or ``bbox_inches="tight"`` would draw every
figure twice over). Legends list only artists that were drawn with data: the helpers
label an artist only when they draw one.

matplotlib is imported inside the functions, on an explicit Agg canvas, so importing this
module costs nothing and pyplot's global backend is left alone.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from hapticframe.kinds import MovementResult, Region

__all__ = [
    "DPI",
    "TRUTH_COLOUR",
    "draw_level_outline",
    "draw_movements",
    "draw_occupancy_map",
    "draw_outlines",
    "draw_path",
    "draw_verdict",
    "layout_map",
    "map_figure",
    "new_figure",
    "save_figure",
]

#: Resolution of every written PNG (dots per inch).
DPI = 110
#: Colour of the true object's outline on every figure.
TRUTH_COLOUR = "tab:green"

Bounds = tuple[float, float, float, float]

# Margins in inches: room for tick labels and axis labels at the default font size.
_LEFT_IN = 0.85
_BOTTOM_IN = 0.55
_TITLE_IN = 0.4
_COLORBAR_IN = (0.18, 0.15, 0.8)  # gap, bar, tick and axis labels
_RIGHT_IN = 0.3
_LEGEND_PAD_IN = 0.2
_LEGEND_FONT = 8
_NOTE_FONT = 7
_NOTE_LINE_IN = 0.13  # a 7-point line with its leading
_NOTE_CHAR_IN = 0.052  # the widest average character of a 7-point line, generous


def new_figure(width_in: float = 7.0, height_in: float = 5.0) -> Figure:
    """A matplotlib Figure on its own Agg canvas (pyplot's global state is not touched)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width_in, height_in), dpi=DPI)
    FigureCanvasAgg(figure)
    return figure


def map_figure(*, colorbar: bool = True) -> tuple[Figure, Axes, Axes | None]:
    """A figure with one map axes and, when asked, a colour-bar axes; lay it out with
    :func:`layout_map` once everything is drawn."""
    figure = new_figure()
    axes = figure.add_axes((0.1, 0.1, 0.7, 0.8))
    colorbar_axes = figure.add_axes((0.85, 0.1, 0.03, 0.8)) if colorbar else None
    return figure, axes, colorbar_axes


def layout_map(
    figure: Figure,
    axes: Axes,
    colorbar_axes: Axes | None,
    bounds: Bounds,
    *,
    width_in: float = 5.0,
    max_height_in: float = 4.0,
    min_width_in: float = 6.0,
    legend_columns: int = 3,
    legend_background: str | None = None,
    note: str = "",
) -> None:
    """Size ``figure`` around a map of ``bounds`` and add the legend of what ``axes`` drew.

    ``note`` (lines of small grey text: what the map is, how to read it) goes below the
    legend, with room made for it.

    The axes box gets the region's aspect, so an equal-aspect map fills it; the legend
    (one entry per labelled artist) goes below the x label, on ``legend_background`` when
    given (a grey lets white lines drawn on a dark map show). Call it last, before saving.
    """
    x0, x1, y0, y1 = bounds
    aspect = (y1 - y0) / (x1 - x0) if x1 > x0 and y1 > y0 else 1.0
    w, h = width_in, width_in * aspect
    if h > max_height_in:
        w, h = max_height_in / aspect, max_height_in
    handles, labels = axes.get_legend_handles_labels()
    legend = None
    legend_w = legend_h = 0.0
    if labels:
        legend = figure.legend(handles, labels, loc="lower center",
                               ncols=max(1, min(legend_columns, len(labels))),
                               fontsize=_LEGEND_FONT, frameon=legend_background is not None)
        if legend_background is not None:
            legend.get_frame().set(facecolor=legend_background, edgecolor="none", alpha=1.0)
        # Measured, not guessed: its size in inches does not depend on the figure's.
        extent = legend.get_window_extent()
        legend_w, legend_h = extent.width / figure.dpi, extent.height / figure.dpi
    note_h = 0.0
    if note:
        # The note's lines widen the figure as the legend does.
        note_h = _NOTE_LINE_IN * (note.count("\n") + 1) + 0.05
        legend_w = max(legend_w, _NOTE_CHAR_IN * max(len(x) for x in note.splitlines()))
    right = sum(_COLORBAR_IN) if colorbar_axes is not None else _RIGHT_IN
    width = max(_LEFT_IN + w + right, min_width_in, legend_w + 2 * _LEGEND_PAD_IN)
    left = _LEFT_IN + (width - (_LEFT_IN + w + right)) / 2  # centre a narrow map
    bottom = _BOTTOM_IN + note_h + (legend_h + _LEGEND_PAD_IN if legend is not None else 0.0)
    title_in = _TITLE_IN if axes.get_title() else 0.15
    height = bottom + h + title_in
    figure.set_size_inches(width, height)
    axes.set_position((left / width, bottom / height, w / width, h / height))
    axes.set_xlim(x0, x1)
    axes.set_ylim(y0, y1)
    axes.set_aspect("equal", adjustable="box")
    if colorbar_axes is not None:
        gap, bar, _ = _COLORBAR_IN
        colorbar_axes.set_position(
            ((left + w + gap) / width, bottom / height, bar / width, h / height)
        )
    if legend is not None:
        legend.set_bbox_to_anchor((0.5, (0.05 + note_h) / height), transform=figure.transFigure)
    if note:
        figure.text(_LEGEND_PAD_IN / width, 0.05 / height, note, fontsize=_NOTE_FONT,
                    color="0.25", ha="left", va="bottom")


def save_figure(figure: Figure, path: str | Path) -> Path:
    """Write ``figure`` as PNG at :data:`DPI`, atomically (the folder is created); return
    ``path``.

    The figure is written to a temporary name beside ``path`` and renamed, so a killed or
    failed save never leaves a truncated or empty file, and never spoils the file that was
    there. Raises :class:`~hapticframe.RunError` naming ``path`` when it cannot be written
    (disk full, no permission).
    """
    from hapticframe._atomic import atomic_path, output_error

    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(path.parent, exc, "cannot create the folder") from exc
    with atomic_path(path) as temp:
        # zlib level 6 (the default) costs a few times level 3 for files a tenth smaller.
        figure.savefig(temp, format=path.suffix.lstrip(".").lower() or "png", dpi=DPI,
                       pil_kwargs={"compress_level": 3})
    return path


def draw_verdict(axes: Axes, verdict: str) -> bool:
    """Write ``verdict`` (a run that found nothing says so on every figure) in a red box
    in the upper-left corner of ``axes``; False, drawing nothing, when it is empty."""
    if not verdict:
        return False
    axes.text(0.01, 0.98, verdict, transform=axes.transAxes, ha="left", va="top",
              fontsize=8, color="darkred", zorder=10,
              bbox={"boxstyle": "round,pad=0.3", "facecolor": "white", "edgecolor": "darkred",
                    "alpha": 0.9})
    return True


def draw_outlines(
    axes: Axes,
    outlines: Iterable[ArrayLike],
    *,
    label: str = "true object",
    colour: str = TRUTH_COLOUR,
    linewidth: float = 1.8,
) -> int:
    """Draw closed outlines (``(n, 2)`` each); one legend entry for all. Returns how many."""
    count = 0
    for outline in outlines:
        ring = np.asarray(outline, dtype=np.float64)
        if ring.ndim != 2 or ring.shape[0] < 2:
            continue
        ring = np.vstack([ring, ring[:1]])
        axes.plot(ring[:, 0], ring[:, 1], color=colour, lw=linewidth,
                  label=label if count == 0 else None)
        count += 1
    return count


def draw_level_outline(
    axes: Axes,
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    values: NDArray[np.float64],
    level: float,
    *,
    label: str | None = None,
    colour: str = "white",
    linestyle: str = "--",
) -> bool:
    """Draw the ``level`` curve of ``values`` (``(len(ys), len(xs))``) as lines; False when
    the values never cross ``level`` (nothing drawn, no legend entry)."""
    from hapticframe.geometry import level_outlines

    rings = [r for r in level_outlines(xs, ys, values, level) if len(r) > 1]
    for index, ring in enumerate(rings):
        axes.plot(ring[:, 0], ring[:, 1], color=colour, lw=1.3, ls=linestyle,
                  label=(label or f"p = {level:g}") if index == 0 else None)
    return bool(rings)


def draw_path(
    axes: Axes,
    points_m: ArrayLike,
    *,
    label: str = "fingertip path",
    colour: str = "black",
    marker_end: bool = True,
) -> bool:
    """Draw the fingertip's path (``(n, 2)``, finite rows only) and a ring at its end."""
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.shape[0] == 0:
        return False
    axes.plot(p[:, 0], p[:, 1], color=colour, lw=1.0, label=label)
    if marker_end:
        axes.plot(p[-1, 0], p[-1, 1], ls="none", marker="o", ms=7, mfc="none", mec=colour,
                  mew=1.5, label="fingertip")
    return True


def draw_movements(
    axes: Axes,
    movements: Sequence[MovementResult],
    *,
    colour: str = "black",
    is_interaction: Callable[[MovementResult], bool] | None = None,
) -> None:
    """Draw each movement from its start to where the fingertip stopped, and a cross where
    a movement interacted (``result.interacted`` unless ``is_interaction`` says otherwise).

    One legend entry each: "fingertip path" and, when any, "interaction".
    """
    interacted = is_interaction or (lambda result: result.interacted)
    xs: list[float] = []
    ys: list[float] = []
    hits: list[NDArray[np.float64]] = []
    for result in movements:
        start = np.asarray(result.movement.start_m, dtype=np.float64)
        stop = _stop_point(result)
        xs += [start[0], stop[0], np.nan]
        ys += [start[1], stop[1], np.nan]
        if interacted(result):
            hits.append(stop)
    if xs:
        # One artist for every segment: NaN breaks the line between movements.
        axes.plot(xs, ys, color=colour, lw=1.0, label="fingertip path")
    if hits:
        h = np.vstack(hits)
        axes.plot(h[:, 0], h[:, 1], ls="none", marker="x", color="tab:red", ms=8, mew=2,
                  label="interaction")


def _stop_point(result: MovementResult) -> NDArray[np.float64]:
    state = result.final_state
    if state is not None and np.all(np.isfinite(state.position_m)):
        return np.asarray(state.position_m, dtype=np.float64)
    return np.asarray(result.movement.end_m, dtype=np.float64)


def draw_occupancy_map(
    region: Region,
    xs: ArrayLike,
    ys: ArrayLike,
    values: ArrayLike,
    *,
    title: str,
    label: str,
    vmax: float,
    outlines: Sequence[ArrayLike] = (),
    movements: Sequence[MovementResult] = (),
    outline_level: float | None = None,
    extra: Callable[[Axes], None] | None = None,
    verdict: str = "",
) -> Figure:
    """An occupancy map's mean or std over ``region``: ``values`` (``(len(ys), len(xs))``)
    from 0 to ``vmax`` on viridis, the true ``outlines`` (magenta: green vanishes into
    viridis), the ``movements`` (white), the ``outline_level`` curve when given, and what
    ``extra`` draws on the axes, and ``verdict`` (:func:`draw_verdict`); returns the
    laid-out Figure (save it with :func:`save_figure`)."""
    x, y = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
    grid = np.asarray(values, dtype=np.float64)
    figure, axes, colorbar_axes = map_figure()
    bounds = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
    image = axes.imshow(grid, origin="lower", extent=bounds, vmin=0.0, vmax=vmax,
                        cmap="viridis", interpolation="nearest")
    figure.colorbar(image, cax=colorbar_axes, label=label)
    if outline_level is not None:
        draw_level_outline(axes, x, y, grid, outline_level,
                           label=f"estimated outline (p = {outline_level:g})")
    draw_outlines(axes, outlines, colour="magenta")
    draw_movements(axes, movements, colour="white")
    if extra is not None:
        extra(axes)
    draw_verdict(axes, verdict)
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title)
    # White lines on the dark map need a grey legend to show.
    layout_map(figure, axes, colorbar_axes, bounds, legend_background="0.6")
    return figure

