"""The sandbox's run figure: fingertip force per exploratory movement (like thesis Fig. 3.6)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hapticframe import Kind, plotting

from ._truth import GroundTruthLog, MovementTruth

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["classifier_force_thresholds", "draw_movement_forces", "plot_movement_forces"]

# Legend rows per column before the movements' legend wraps into another column.
_LEGEND_ROWS = 18
_PANELS_IN = (10.0, 4.2)
_LEGEND_COLUMN_IN = 1.95


def draw_movement_forces(
    log: GroundTruthLog,
    movements: Sequence[MovementTruth],
    *,
    thresholds: Mapping[str, float] | None = None,
    verdict: str = "",
) -> Figure:
    """The true plate force's magnitude (the simulator's, no sensor noise) against time for
    every movement, with the true interaction state and the decision thresholds.

    Left: time since each movement started; the samples the simulator labels jamming or
    contact underlaid in a broad orange or red band, every jamming onset a circle, every
    contact onset a cross, in the movement's colour (each kind in the legend only when one
    happened). Right: movements that jammed, aligned at the jamming onset (dashed line at
    0 s). ``thresholds`` (name to newtons, e.g. a classifier's jamming and contact force
    thresholds) are horizontal lines on both panels. The legend beside the panels names
    each movement and its depth; ``verdict`` is written in the left panel's corner.
    """
    # Movements, onsets, state bands and thresholds.
    entries = len(movements) + 4 + len(thresholds or {})
    columns = max(1, math.ceil(entries / _LEGEND_ROWS))
    width = _PANELS_IN[0] + columns * _LEGEND_COLUMN_IN
    figure = plotting.new_figure(width, _PANELS_IN[1])
    figure.subplots_adjust(left=0.6 / width, right=(_PANELS_IN[0] - 0.1) / width, bottom=0.12,
                           top=0.92, wspace=0.22)
    ax_all, ax_aligned = figure.subplots(1, 2)
    magnitude = log.force_magnitude_n
    # Ten colours repeat after ten movements; twenty keep up to twenty apart.
    palette = [f"C{i}" for i in range(10)] if len(movements) <= 10 else _tab20()
    seen_states: set[str] = set()
    onsets: dict[str, tuple[list[float], list[float], list[str]]] = {
        "true jamming onset": ([], [], []), "true contact onset": ([], [], [])}
    for number, truth in enumerate(movements):
        rows = log.movement_index == truth.index
        if not rows.any():
            continue
        colour = palette[number % len(palette)]
        t = log.timestamps_s[rows]
        f = magnitude[rows]
        label = f"EM {truth.index + 1}, depth {100 * truth.depth_m:.2f} cm"
        states = log.states[rows]
        for state, (band, name) in _STATE_BANDS.items():
            if np.any(states == state):
                ax_all.plot(t - truth.start_time_s, np.where(states == state, f, np.nan),
                            color=band, lw=5.0, alpha=0.35, solid_capstyle="butt",
                            label=None if name in seen_states else name, zorder=1)
                seen_states.add(name)
        ax_all.plot(t - truth.start_time_s, f, color=colour, lw=1.0, label=label, zorder=2)
        for name, onset in (("true jamming onset", truth.jamming_onset_s),
                            ("true contact onset", truth.contact_onset_s)):
            if not math.isnan(onset):
                k = min(int(np.searchsorted(t, onset)), f.size - 1)
                onsets[name][0].append(onset - truth.start_time_s)
                onsets[name][1].append(float(f[k]))
                onsets[name][2].append(colour)
        if not math.isnan(truth.jamming_onset_s):
            ax_aligned.plot(t - truth.jamming_onset_s, f, color=colour, lw=1.0)
    for (name, (xs, ys, colours)), marker in zip(onsets.items(), ("o", "X"), strict=True):
        if xs:
            ax_all.scatter(xs, ys, c=colours, marker=marker, s=45, edgecolors="black",
                           linewidths=0.6, zorder=3, label=name)
    if any(not math.isnan(m.jamming_onset_s) for m in movements):
        ax_aligned.axvline(0.0, color="k", ls="--", lw=1.0)
    for number, (name, value) in enumerate((thresholds or {}).items()):
        style = _THRESHOLD_STYLES[number % len(_THRESHOLD_STYLES)]
        for ax in (ax_all, ax_aligned):
            ax.axhline(value, color="0.2", ls=style, lw=1.0,
                       label=f"{name} {value:g} N" if ax is ax_all else None)
    for ax in (ax_all, ax_aligned):
        ax.set_ylabel("true plate force |F| (simulator, N)")
        ax.grid(alpha=0.3)
    ax_all.set_xlabel("time since movement start (s)")
    ax_all.set_title("true force per movement (no sensor noise)")
    plotting.draw_verdict(ax_all, verdict)
    ax_aligned.set_xlabel("time since jamming onset (s)")
    ax_aligned.set_title("movements that jammed, aligned at onset")
    handles, labels = ax_all.get_legend_handles_labels()
    if labels:
        figure.legend(handles, labels, loc="upper left", fontsize=7, ncols=columns,
                      bbox_to_anchor=(_PANELS_IN[0] / width, 0.92), frameon=False)
    return figure


# The simulator's interaction states (ground_truth.npz ``state``) drawn as bands.
_STATE_BANDS = {1: ("tab:orange", "true state: jamming"), 2: ("tab:red", "true state: contact")}
_THRESHOLD_STYLES = (":", "-.", (0, (5, 2, 1, 2)))


def classifier_force_thresholds(components: Mapping[str, object]) -> dict[str, float]:
    """The force thresholds of the run's threshold classifiers, by name, for the figure.

    A classifier that exposes ``thresholds`` as (jamming force, jamming rate, contact force,
    contact rate), as ``force-rate-jamming`` does, contributes its two force thresholds;
    the rate thresholds are on a force rate, which this figure does not draw.
    """
    out: dict[str, float] = {}
    for cid, component in components.items():
        if getattr(component, "kind", None) != Kind.CLASSIFIER:
            continue
        values = getattr(component, "thresholds", None)
        if isinstance(values, tuple) and len(values) == 4:
            try:
                jam, _, contact, _ = (float(v) for v in values)
            except (TypeError, ValueError):
                continue
            if math.isfinite(jam) and math.isfinite(contact):
                out[f"{cid}: jamming force threshold"] = jam
                out[f"{cid}: contact force threshold"] = contact
    if len(out) == 2:  # one classifier: its id says nothing the legend needs
        out = {name.split(": ", 1)[1]: value for name, value in out.items()}
    return out


def _tab20() -> list[str]:
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    return [str(to_hex(colormaps["tab20"](i))) for i in range(20)]


def plot_movement_forces(
    log: GroundTruthLog,
    movements: Sequence[MovementTruth],
    path: Path,
    *,
    thresholds: Mapping[str, float] | None = None,
    verdict: str = "",
) -> Path | None:
    """Write :func:`draw_movement_forces` as PNG at ``path``.

    Returns
    -------
    Path or None
        The written file, or None when matplotlib is not installed (a warning says so).
    """
    try:
        figure = draw_movement_forces(log, movements, thresholds=thresholds, verdict=verdict)
    except ImportError:  # plots are an optional extra
        warnings.warn("matplotlib is not installed; forces.png was not written", stacklevel=2)
        return None
    return plotting.save_figure(figure, path)
