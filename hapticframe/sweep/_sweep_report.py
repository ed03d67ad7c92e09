"""``sweep.md`` and ``pareto.png``: the report of a :func:`hapticframe.sweep._sweep.run_sweep`
result (a table per knob, the Pareto fronts over all points, the figure)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe.sweep._format import flow_text, format_value, unchanged
from hapticframe.sweep._sweep_trials import SEARCH_KEYS, _is_onset_key

__all__ = ["render_markdown", "save_pareto_figure"]


def _table_keys(points: Sequence[Mapping[str, Any]]) -> list[str]:
    keys = sorted({k for p in points for k in p["metrics"]})
    shown_keys = [k for k in SEARCH_KEYS if k in keys]
    shown_keys += [k for k in keys if k.endswith("_balanced_accuracy")]
    shown_keys += [k for k in keys if _is_onset_key(k)]
    shown_keys += [k for k in keys if "auc" in k or "log_loss" in k]
    return list(dict.fromkeys(shown_keys))


def _rows(points: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[str]:
    named = {"object_found": "found (share)"}
    head = ["point", "status", "ok/trials", *[named.get(k, k) for k in keys], "wall s",
            "CPU s", "wall per step ms", "peak RSS MB"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in points:
        found = p["metrics"]
        cost = p["cost"]
        rss = cost.get("peak_rss_bytes")
        per_step = cost.get("wall_time_per_step_s")
        cells = [("**" + p["label"] + "**") if p.get("front") else p["label"], p["status"],
                 f"{p['trials_ok']}/{p['trials']}",
                 *[format_value(found.get(k)) for k in keys],
                 format_value(cost.get("wall_time_s")), format_value(cost.get("cpu_time_s")),
                 format_value(None if per_step is None else per_step * 1e3),
                 format_value(None if rss is None else rss / 2**20)]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return lines


def render_markdown(result: Mapping[str, Any]) -> str:
    """``sweep.md``: a table per knob, the Pareto front, and the points that failed."""
    points = result["points"]
    keys = _table_keys(points)
    accuracy = result.get("accuracy")
    lines = [f"# Sweep of {result['experiment_file']}", "",
             f"{result['mode'].capitalize()}, {result['trials']} trial(s) per point (seeds "
             f"{', '.join(map(str, result['seeds']))}), {result['workers']} "
             f"{result['executor']} worker(s); metrics are means over a point's finished "
             "trials, costs per run. Bold: on the Pareto front.", ""]
    if result.get("overrides"):
        lines += ["Every point with: " + ", ".join(f"`--set {o}`" for o in result["overrides"]),
                  ""]
    machine = result.get("machine") or {}
    load = machine.get("load_average_1min") or {}
    if load.get("start") is not None:
        lines += [f"Machine load (1-minute average) {format_value(load['start'])} at the start "
                  f"and {format_value(load.get('end'))} at the end, on "
                  f"{machine.get('cpu_count')} CPUs: "
                  "where it exceeds the CPUs, wall times include waiting for a core, so "
                  "read the CPU-time front below.", ""]
    baseline = points[0]
    for knob in result["knobs"]:
        path = knob["path"]
        lines += [f"## {path}", ""]
        if knob.get("trades"):
            lines += [f"Trades: {knob['trades']}", ""]
        lines += [f"File's value: {format_value(knob['baseline'])}; tried: "
                  f"{', '.join(flow_text(v) for v in knob['values'])}.", ""]
        if result["mode"] == "grid":
            chosen = [p for p in points if any(v["path"] == path for v in p["values"])]
        else:
            chosen = [baseline, *[p for p in points if [v["path"] for v in p["values"]] == [path]]]
        lines += [*_rows(chosen, keys), ""]
        if result["mode"] != "grid" and unchanged(chosen, keys):
            lines += ["No accuracy metric changed at any value tried: at these seeds this "
                      "knob buys nothing here.", ""]
    lines += ["## Pareto front", ""]
    if accuracy is None:
        lines += ["The runs report no accuracy metric to weigh against time.", ""]
    else:
        found = any("object_found" in p["metrics"] for p in points)
        lines += [f"Accuracy: {accuracy['description']} (lower is better; a mean over the "
                  "trials that report it: a search that estimates no centroid has none, so "
                  "read it beside object_found, the share of trials that found the object) "
                  "against mean time per run; a point is on the front when no other point "
                  "is both faster and more accurate."
                  + (" A point that found the object in fewer of its trials than the best "
                     "points is kept off the fronts." if found else ""), ""]
        for key, cost_key, what in (("front", "wall_time_s", "wall time"),
                                    ("front_cpu", "cpu_time_s", "CPU time")):
            front = sorted((p for p in points if p.get(key)),
                           key=lambda p: p["cost"].get(cost_key) or 0.0)
            lines += [f"Against {what}:", "",
                      "| point | accuracy cost | found (share) | wall s | CPU s |",
                      "|---|---|---|---|---|"]
            lines += [f"| {p['label']} | {format_value(p['accuracy_cost'])} | "
                      f"{format_value(p['metrics'].get('object_found'))} | "
                      f"{format_value(p['cost'].get('wall_time_s'))} | "
                      f"{format_value(p['cost'].get('cpu_time_s'))} |" for p in front]
            lines.append("")
        off = [p for p in points if p.get("off_front")]
        if off:
            lines += ["Kept off the fronts:", ""]
            lines += [f"- {p['label']}: {p['off_front']}" for p in off]
            lines.append("")
    failed = [p for p in points if p["status"] != "ok"]
    if failed:
        lines += ["## Points that failed", ""]
        for p in failed:
            errors = "; ".join(e.replace("\n", " ") for e in p["errors"]) or p["status"]
            lines.append(f"- {p['label']}: {p['status']}: {errors[:500]}")
        lines.append("")
    warned = [p for p in points if p.get("warnings")]
    if warned:
        lines += ["## Points whose runs warned", ""]
        lines += [f"- {p['label']}: {p['warnings']} warning(s), e.g. "
                  f"{'; '.join(p.get('warning_messages') or [])[:300]}" for p in warned]
        lines.append("")
    return "\n".join(lines)


#: A sweep with more points than this names only its front and its baseline in pareto.png.
LABEL_ALL_UP_TO = 12
#: The cost pareto.png weighs accuracy against: mean CPU time per run, which a busy machine
#: does not inflate as it does wall time (docs/sweeps.md, "Two fronts").
PARETO_COST = "cpu_time_s"
#: A point's label is tried in this many directions around it (from the right, counter-
#: clockwise), at distances of 1 to :data:`_LABEL_RINGS` steps of :data:`_LABEL_STEP_PT`.
_LABEL_DIRECTIONS = 16
_LABEL_STEP_PT = 5.0
_LABEL_RINGS = 40
#: Half the side of the square around each drawn point that no label covers (points).
_MARK_HALF_PT = 7.0
# The figure's margins in inches: tick and axis labels at the left and bottom, the title.
_LEFT_IN, _RIGHT_IN, _TITLE_IN, _XLABEL_IN, _LEGEND_PAD_IN = 0.9, 0.25, 0.45, 0.55, 0.12


def _cost(point: Mapping[str, Any]) -> float | None:
    value = point["cost"].get(PARETO_COST)
    return None if value is None else float(value)


def _spread(point: Mapping[str, Any], table: str, key: str | None) -> float:
    """A point's standard deviation over its trials of ``key`` in ``table``; 0 when
    unknown (one finished trial, or a metric with no spread recorded)."""
    if key is None or point.get("trials_ok", 0) < 2:
        return 0.0
    value = (point.get(table) or {}).get(key)
    return float(value) if isinstance(value, (int, float)) and value == value else 0.0


def _align(component: float) -> tuple[str, float]:
    """The alignment of a label whose offset from its point has this unit ``component``,
    and where that puts the label's near edge, as a share of its size back from its anchor."""
    if component > 0.3:
        return "left", 0.0
    if component < -0.3:
        return "right", 1.0
    return "center", 0.5


def _place_labels(figure: Any, ax: Any, items: Sequence[tuple[str, float, float]],
                  marks: Sequence[tuple[float, float]]) -> list[Any]:
    """Annotate each (label, x, y) near its point, where no other label and no point of
    ``marks`` is and inside the axes: the nearest free place at growing distances in
    :data:`_LABEL_DIRECTIONS` directions, joined to its point by a thin line once it had to
    move away. Returns the annotations; a label with no free place within reach is left out
    (``sweep.md`` names every point)."""
    from matplotlib.transforms import Bbox

    renderer = figure.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    scale = figure.dpi / 72.0
    half = _MARK_HALF_PT * scale
    anchors = ax.transData.transform(np.asarray(marks, dtype=float).reshape(-1, 2))
    taken = [Bbox.from_extents(px - half, py - half, px + half, py + half)
             for px, py in anchors]
    angles = np.arange(_LABEL_DIRECTIONS) * (2 * np.pi / _LABEL_DIRECTIONS)
    style = {"fontsize": 6, "zorder": 5, "textcoords": "offset points",
             "bbox": {"boxstyle": "round,pad=0.15", "facecolor": "white",
                      "edgecolor": "none", "alpha": 0.85}}
    placed: list[Any] = []
    for label, x, y in items:
        probe = ax.annotate(label, (x, y), xytext=(0.0, 0.0), **style)
        size = probe.get_window_extent(renderer)
        probe.remove()
        width, height = size.width * 1.05, size.height * 1.1
        px, py = ax.transData.transform((x, y))
        choice = None
        for ring in range(1, _LABEL_RINGS + 1):
            for angle in angles:
                cos, sin = float(np.cos(angle)), float(np.sin(angle))
                ha, back_x = _align(cos)
                va, back_y = _align(sin)
                va = {"left": "bottom", "right": "top"}.get(va, va)
                dx, dy = ring * _LABEL_STEP_PT * cos, ring * _LABEL_STEP_PT * sin
                x0 = px + dx * scale - back_x * width
                y0 = py + dy * scale - back_y * height
                box = Bbox.from_bounds(x0, y0, width, height)
                if (box.x0 >= frame.x0 and box.x1 <= frame.x1 and box.y0 >= frame.y0
                        and box.y1 <= frame.y1
                        and not any(box.overlaps(other) for other in taken)):
                    choice = (dx, dy, ha, va, ring, box)
                    break
            if choice is not None:
                break
        if choice is None:
            continue
        dx, dy, ha, va, ring, box = choice
        arrow = None if ring <= 2 else {"arrowstyle": "-", "color": "0.6", "linewidth": 0.5}
        placed.append(ax.annotate(label, (x, y), xytext=(dx, dy), ha=ha, va=va,
                                  arrowprops=arrow, **style))
        taken.append(box)
    return placed


def save_pareto_figure(path: Path, result: Mapping[str, Any]) -> bool:
    """``pareto.png``: accuracy cost against mean CPU time per run (:data:`PARETO_COST`),
    every finished point with its seed spread (one standard deviation of both over its
    trials) when it had more than one, the CPU-time front highlighted, the labels placed
    where none overprints another, and the legend below the axes inside the figure; False
    when matplotlib is not installed."""
    try:
        from hapticframe.plotting import new_figure, save_figure

        figure = new_figure(8.0, 5.5)
    except ImportError:
        return False
    ax = figure.add_axes((0.1, 0.3, 0.85, 0.6))
    accuracy = result.get("accuracy")
    metric = accuracy.get("metric") if accuracy else None
    plotted = [p for p in result["points"]
               if p.get("accuracy_cost") is not None and _cost(p) is not None]
    front = [p for p in plotted if p.get("front_cpu")]
    off = [p for p in plotted if p.get("off_front")]
    others = [p for p in plotted if not p.get("front_cpu") and not p.get("off_front")]
    # A search that missed the object reports a cost far above the rest (18 cm against
    # 1-3 cm in the README's sweep) and would squash the front into the axis: such points
    # are drawn at the top edge, their values in sweep.md.
    kept = [p["accuracy_cost"] for p in plotted if not p.get("off_front")]
    top = max(kept) * 1.15 if kept and max(kept) > 0 else None
    clipped = {id(p) for p in off if top is not None and p["accuracy_cost"] > top}
    x: dict[int, float] = {id(p): _cost(p) or 0.0 for p in plotted}
    y: dict[int, float] = {id(p): float(top if top is not None and id(p) in clipped
                                        else p["accuracy_cost"]) for p in plotted}
    spread = [p for p in plotted if p.get("trials_ok", 0) > 1]
    if spread:
        trials = sorted({int(p["trials_ok"]) for p in spread})
        ax.errorbar([x[id(p)] for p in spread], [y[id(p)] for p in spread],
                    xerr=[_spread(p, "cost_std", PARETO_COST) for p in spread],
                    yerr=[0.0 if id(p) in clipped else _spread(p, "metrics_std", metric)
                          for p in spread],
                    fmt="none", ecolor="0.55", elinewidth=0.8, capsize=2, zorder=1,
                    label="seed spread: \u00b11 s.d. over "
                          + "/".join(map(str, trials)) + " trials")
    if off:
        ax.scatter([x[id(p)] for p in off], [y[id(p)] for p in off],
                   color="tab:gray", marker="x", zorder=2,
                   label="missed the object in some trials (at most the top edge)")
    if others:
        ax.scatter([x[id(p)] for p in others], [y[id(p)] for p in others],
                   color="tab:gray", marker="o", zorder=2, label="point")
    front.sort(key=lambda p: x[id(p)])
    if front:
        ax.plot([x[id(p)] for p in front], [y[id(p)] for p in front],
                color="tab:red", marker="o", linestyle="-", zorder=3,
                label="Pareto front (CPU time)")
    base = result["points"][0]
    if id(base) in x:
        ax.scatter([x[id(base)]], [y[id(base)]], s=160, facecolors="none",
                   edgecolors="black", zorder=4, label="baseline (the file)")
    # Every label of a large sweep would be a pile of text: then only the front and the
    # baseline are named (sweep.md lists every point).
    named = plotted if len(plotted) <= LABEL_ALL_UP_TO else [
        p for p in plotted if p.get("front_cpu") or p is base]
    failed = sum(1 for p in result["points"] if p.get("accuracy_cost") is None)
    ax.set_xlabel("mean CPU time per run (s)")
    ax.set_ylabel(accuracy["description"] if accuracy else "no accuracy metric")
    ax.set_title(f"{result['experiment_file']}: {len(plotted)} points"
                 + (", the front named" if len(named) < len(plotted) else "")
                 + (f", {failed} without a finite accuracy (see sweep.md)" if failed else ""),
                 fontsize=9)
    width, height = figure.get_size_inches()
    legend_h = 0.0
    if plotted:
        handles, labels = ax.get_legend_handles_labels()
        legend = figure.legend(handles, labels, loc="lower center", ncols=2, fontsize=8,
                               bbox_to_anchor=(0.5, _LEGEND_PAD_IN / height),
                               bbox_transform=figure.transFigure)
        legend_h = legend.get_window_extent().height / figure.dpi + 2 * _LEGEND_PAD_IN
    else:
        ax.text(0.5, 0.5, "no point finished with an accuracy", ha="center",
                transform=ax.transAxes)
    bottom = legend_h + _XLABEL_IN
    ax.set_position((_LEFT_IN / width, bottom / height,
                     (width - _LEFT_IN - _RIGHT_IN) / width,
                     (height - bottom - _TITLE_IN) / height))
    # The limits as drawn, then fixed, so that the labels are placed where they will be.
    ax.margins(0.08, 0.1)
    ax.autoscale_view()
    ax.set_xlim(ax.get_xlim())
    ax.set_ylim(ax.get_ylim())
    _place_labels(figure, ax, [(str(p["label"]), x[id(p)], y[id(p)])
                               for p in sorted(named, key=lambda p: x[id(p)])],
                  [(x[id(p)], y[id(p)]) for p in plotted])
    save_figure(figure, path)
    return True
