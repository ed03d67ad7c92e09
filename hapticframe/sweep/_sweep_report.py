"""``sweep.md`` and ``pareto.png``: the report of a :func:`hapticframe.sweep._sweep.run_sweep`
result (a table per knob, the Pareto fronts over all points, the figure)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

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


def save_pareto_figure(path: Path, result: Mapping[str, Any]) -> bool:
    """``pareto.png``: accuracy cost against mean wall time, every finished point, the
    front highlighted; False when matplotlib is not installed."""
    try:
        from hapticframe.plotting import new_figure, save_figure

        figure = new_figure(9.5, 5.0)
    except ImportError:
        return False
    ax = figure.add_subplot(1, 1, 1)
    accuracy = result.get("accuracy")
    plotted = [p for p in result["points"] if p.get("accuracy_cost") is not None]
    front = sorted((p for p in plotted if p.get("front")),
                   key=lambda p: p["cost"]["wall_time_s"])
    off = [p for p in plotted if p.get("off_front")]
    others = [p for p in plotted if not p.get("front") and not p.get("off_front")]
    # A search that missed the object reports a cost far above the rest (18 cm against
    # 1-3 cm in the README's sweep) and would squash the front into the axis: such points
    # are drawn at the top edge, their values in sweep.md.
    kept = [p["accuracy_cost"] for p in plotted if not p.get("off_front")]
    top = max(kept) * 1.15 if kept and max(kept) > 0 else None
    y = {id(p): (min(p["accuracy_cost"], top) if top is not None and p.get("off_front")
                 else p["accuracy_cost"]) for p in plotted}
    if off:
        ax.scatter([p["cost"]["wall_time_s"] for p in off], [y[id(p)] for p in off],
                   color="tab:gray", marker="x",
                   label="missed the object in some trials (at most the top edge)")
    if others:
        ax.scatter([p["cost"]["wall_time_s"] for p in others],
                   [p["accuracy_cost"] for p in others], color="tab:gray", marker="o",
                   label="point")
    if front:
        ax.plot([p["cost"]["wall_time_s"] for p in front], [p["accuracy_cost"] for p in front],
                color="tab:red", marker="o", linestyle="-", label="Pareto front")
    base = result["points"][0]
    if base.get("accuracy_cost") is not None:
        ax.scatter([base["cost"]["wall_time_s"]], [base["accuracy_cost"]], s=160,
                   facecolors="none", edgecolors="black", label="baseline (the file)")
    times = [p["cost"]["wall_time_s"] for p in plotted]
    middle = (min(times) + max(times)) / 2 if times else 0.0
    # Every label of a large sweep would be a pile of text: then only the front and the
    # baseline are named (sweep.md lists every point).
    named = plotted if len(plotted) <= LABEL_ALL_UP_TO else [
        p for p in plotted if p.get("front") or p is base]
    for number, p in enumerate(sorted(named, key=lambda p: p["cost"]["wall_time_s"])):
        # Labels point inwards, so that those of the rightmost points are not cut off, and
        # alternate above and below the line, so that neighbours on the front do not overlap.
        right = p["cost"]["wall_time_s"] > middle
        ax.annotate(p["label"], (p["cost"]["wall_time_s"], y[id(p)]), fontsize=6,
                    xytext=(-3 if right else 3, 4 if number % 2 == 0 else -9),
                    textcoords="offset points", ha="right" if right else "left")
    failed = sum(1 for p in result["points"] if p.get("accuracy_cost") is None)
    ax.set_xlabel("mean wall time per run (s)")
    ax.set_ylabel(accuracy["description"] if accuracy else "no accuracy metric")
    ax.set_title(f"{result['experiment_file']}: {len(plotted)} points"
                 + (", the front named" if len(named) < len(plotted) else "")
                 + (f", {failed} without a finite accuracy (see sweep.md)" if failed else ""),
                 fontsize=9)
    if plotted:
        # Beside the axes, not over the points.
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)
    else:
        ax.text(0.5, 0.5, "no point finished with an accuracy", ha="center",
                transform=ax.transAxes)
    save_figure(figure, path)
    return True
