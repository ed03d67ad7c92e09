"""The search benchmark's report: a Markdown table in the form of Table 3.2 and a figure.

Both are written from the summary that ``search.json`` holds, so a report can be rebuilt
from a saved ``search.json`` without running anything.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hapticframe import atomic_path
from hapticframe.kinds import OUTLINE_LEVEL

from ._targets import record_rows

__all__ = [
    "THESIS_TABLE_3_2",
    "draw_trial_figure",
    "format_mean_std",
    "render_markdown",
    "save_trial_figure",
]

#: Table 3.2 of the dissertation (25 simulated trials per shape): mean and std of the
#: number of phase-1 and phase-2 movements, the centroid RMSE and the Hausdorff distance
#: (lengths in metres).
THESIS_TABLE_3_2: dict[str, dict[str, tuple[float, float]]] = {
    "circle": {
        "ems_phase1": (2.5, 1.2),
        "ems_phase2": (4.7, 1.6),
        "centroid_rmse_m": (0.015, 0.005),
        "hausdorff_m": (0.014, 0.005),
    },
    "ellipse": {
        "ems_phase1": (3.0, 1.6),
        "ems_phase2": (4.0, 1.8),
        "centroid_rmse_m": (0.020, 0.003),
        "hausdorff_m": (0.049, 0.006),
    },
}

_DASH = "–"


def _number(value: Any) -> float | None:
    if value is None or isinstance(value, bool):
        return None
    number = float(value)
    return number if math.isfinite(number) else None


def format_mean_std(stats: Mapping[str, Any] | None, *, scale: float = 1.0, digits: int = 1,
                    unit: str = "") -> str:
    """``"m ± s unit"`` of a ``{"mean", "std"}`` summary (a dash when it is empty)."""
    if not stats:
        return _DASH
    mean, std = _number(stats.get("mean")), _number(stats.get("std"))
    if mean is None:
        return _DASH
    text = f"{mean * scale:.{digits}f} ± {(std or 0.0) * scale:.{digits}f}"
    return f"{text} {unit}".rstrip()


def _cm(value: Any, digits: int = 1) -> str:
    number = _number(value)
    return _DASH if number is None else f"{number * 100:.{digits}f} cm"


def _thesis_row(shape: str) -> list[str]:
    row = THESIS_TABLE_3_2[shape]
    return [
        f"{row['ems_phase1'][0]:.1f} ± {row['ems_phase1'][1]:.1f}",
        f"{row['ems_phase2'][0]:.1f} ± {row['ems_phase2'][1]:.1f}",
        f"{row['centroid_rmse_m'][0] * 100:.1f} ± {row['centroid_rmse_m'][1] * 100:.1f} cm",
        f"{row['hausdorff_m'][0] * 100:.1f} ± {row['hausdorff_m'][1] * 100:.1f} cm",
        _DASH,
    ]


def _run_row(group: Mapping[str, Any]) -> list[str]:
    centroid = f"{_cm(group.get('centroid_rmse_m'))} (error " + format_mean_std(
        group.get("centroid_error_m"), scale=100.0, unit="cm") + ")"
    completed = group.get("completed", 0)
    found = f"{group.get('found', 0)}/{completed}"
    if group.get("failed"):
        found += f" ({group['failed']} failed)"
    return [
        format_mean_std(group.get("ems_phase1")),
        format_mean_std(group.get("ems_phase2")),
        centroid,
        format_mean_std(group.get("hausdorff_m"), scale=100.0, unit="cm"),
        found,
    ]


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return lines


def _groups(summary: Mapping[str, Any]) -> list[tuple[str, str, Mapping[str, Any]]]:
    planners = summary.get("planners", {})
    out = []
    for shape in summary.get("shapes", ("circle", "ellipse")):
        out.append((shape, str(planners.get("search", "two-phase-coverage")), summary[shape]))
        if "thesis_params" in summary:
            out.append((shape,
                        f"{planners.get('thesis-params', 'two-phase-coverage')} (Table 3.1)",
                        summary["thesis_params"][shape]))
        out.append((shape, f"{planners.get('baseline', 'coverage')} (baseline)",
                    summary["baseline"][shape]))
    return out


def _objects_section(summary: Mapping[str, Any]) -> list[str]:
    """Found, missed and false blobs per multi-object scene and planner (issue 19 §3)."""
    rows = []
    for shape, label, group in _groups(summary):
        counts = group.get("objects")
        if isinstance(counts, Mapping):
            rows.append([shape, label, str(group.get("completed", 0)),
                         str(counts.get("objects_total")), str(counts.get("objects_found")),
                         str(counts.get("objects_missed")), str(counts.get("false_blobs")),
                         f"{group.get('found', 0)}/{group.get('completed', 0)}"])
    if not rows:
        return []
    return [
        "## Every object (scenes of several objects)", "",
        *_table(["Scene", "Planner", "Trials", "Objects", "Found", "Missed", "False blobs",
                 "Trials with every object found"], rows),
        "",
        "Estimated blobs (connected regions at the outline level, at least 1 cm²) are "
        "matched to the true objects by the Hungarian assignment on centroid distance; an "
        "object is found when its blob's centroid lies within the object's reach. In the "
        "table above such a scene's centroid error and Hausdorff distance are its worst "
        "found object's.", "",
    ]


def _hull_gap_m(shape: str) -> float | None:
    """How far a concave shape's convex hull strays from its outline (0 for a convex one)."""
    from ._placements import Placement

    try:
        obj = Placement(shape, 0, (0.0, 0.0), 0.0).scene_object()
    except ValueError:
        return None
    if obj.get("shape") != "polygon":
        return None
    import numpy as np
    from scipy.spatial import ConvexHull

    from hapticframe import Scene
    from hapticframe.geometry import directed_hausdorff_both

    outline = Scene.model_validate({"objects": [obj], "region": {
        "x_min_m": -1, "x_max_m": 1, "y_min_m": -1, "y_max_m": 1}}).objects[0].outline(1024)
    hull = outline[ConvexHull(outline).vertices]
    closed = np.vstack([hull, hull[:1]])
    t = np.linspace(0.0, 1.0, 64)[:, None]
    ring = np.vstack([a + t * (b - a) for a, b in itertools.pairwise(closed)])
    return directed_hausdorff_both(ring, outline)[0]


def _concavity_section(summary: Mapping[str, Any]) -> list[str]:
    """Whether the level set follows each concave polygon or bridges its concavities."""
    lines = []
    for shape, label, group in _groups(summary):
        gap = _hull_gap_m(shape)
        est = (group.get("hausdorff_est_to_true_m") or {}).get("mean")
        if gap is None or est is None:
            continue
        bridged = est >= 0.6 * gap
        lines.append(
            f"- {shape}, {label}: the convex hull lies up to {gap * 100:.1f} cm outside the "
            f"true outline; the estimated outline strays {est * 100:.1f} cm (mean est→true). "
            + ("The 0.6 level set bridges the concavity: the estimate is nearer the hull "
               "than the shape." if bridged else
               "The level set follows the concavity to better than 60 % of its depth."))
    if not lines:
        return []
    return ["## Concave outlines", "", *lines, ""]


def render_markdown(summary: Mapping[str, Any]) -> str:
    """The Markdown report of a search-benchmark summary (the content of ``search.md``)."""
    machine = summary.get("machine", {})
    wall = _number(summary.get("wall_time_s")) or 0.0
    lines = [
        "# Haptic search benchmark (dissertation Table 3.2)",
        "",
        f"Command: `{summary.get('command', '')}`",
        "",
        f"{summary.get('trials')} trial(s) per shape and planner, seed {summary.get('seed')}; "
        "each trial buries one object at a random position and orientation inside the "
        "75 × 50 cm region (circle: 8 cm diameter; ellipse: 9 × 5 cm) and runs every "
        "planner on the same placement (Table 3.1: the two-phase planner with the "
        "dissertation's own parameters instead of the bundled defaults).",
        "",
        *([] if set(summary.get("shapes", ())) <= set(THESIS_TABLE_3_2) else [
            "Beyond the thesis (issue 19): `l-shape` and `star` are concave polygons of the "
            "circle's area (an 8.2 cm L with a 4.1 cm notch; a 5-point star of outer radius "
            "5.9 cm, inner 2.9 cm); `two-objects` buries a circle and an ellipse, "
            "`three-objects` adds an L-shape, their outlines at least 10 cm apart, and the "
            "two-phase planner searches until the phase-1 lines are exhausted "
            "(`max_objects: null`).", ""]),
        f"Total wall time: {wall:.1f} s ({wall / 60:.1f} min) on {machine.get('platform', '?')}, "
        f"{machine.get('cpu_count', '?')} CPUs, Python {machine.get('python', '?')}.",
        "",
        "## Results beside the thesis",
        "",
    ]
    header = ["Shape", "Source", "# Phase 1 EMs", "# Phase 2 EMs", "Centroid RMSE",
              "Hausdorff distance", "Found"]
    rows = []
    for shape in summary.get("shapes", ("circle", "ellipse")):
        if shape in THESIS_TABLE_3_2:
            rows.append([shape.capitalize(), "thesis (Jia 2022, 25 trials)", *_thesis_row(shape)])
        for group_shape, label, group in _groups(summary):
            if group_shape == shape:
                rows.append([shape.capitalize(), label, *_run_row(group)])
    lines += _table(header, rows)
    lines += [
        "",
        "Centroid RMSE is the root mean square of the per-trial centroid errors, with their "
        "mean ± std in brackets (the thesis reports RMSE ± std). The Hausdorff distance is "
        "the larger of the two directed distances between the estimated outline (occupancy "
        f"{summary.get('outline_level', OUTLINE_LEVEL)} of the evaluated map) and the true "
        "outline. "
        "Standard deviations are population standard deviations. Lengths are summarised "
        "over the trials that found the object; movement counts over all completed trials.",
        "",
    ]
    lines += _objects_section(summary) + _concavity_section(summary)
    if summary.get("targets"):
        lines += ["## Targets (two-phase planner against Table 3.2)", "",
                  *record_rows(summary["targets"]), ""]
    lines += [
        "## Details",
        "",
    ]
    header = ["Shape", "Planner", "Completed", "Failed", "Interactions", "Max force",
              "Runs over force limit", "Movements", "Hausdorff est→true", "Hausdorff true→est",
              "Run wall time"]
    rows = []
    for shape, label, group in _groups(summary):
        exceeded = group.get("force_limit_exceeded")
        rows.append([
            shape.capitalize(),
            label,
            str(group.get("completed", 0)),
            str(group.get("failed", 0)),
            format_mean_std(group.get("object_interactions")),
            format_mean_std(group.get("max_force_n"), unit="N"),
            _DASH if exceeded is None else f"{exceeded} (limit {group.get('force_limit_n')} N)",
            format_mean_std(group.get("movements")),
            format_mean_std(group.get("hausdorff_est_to_true_m"), scale=100.0, unit="cm"),
            format_mean_std(group.get("hausdorff_true_to_est_m"), scale=100.0, unit="cm"),
            format_mean_std(group.get("wall_time_s"), unit="s"),
        ])
    lines += _table(header, rows)
    failures = [(shape, label, f) for shape, label, group in _groups(summary)
                for f in group.get("failures", [])]
    lines += ["", "## Failed runs", ""]
    if failures:
        lines += [f"- {shape} trial {f.get('index')}, {label}: {f.get('error')}"
                  for shape, label, f in failures]
    else:
        lines.append("None.")
    lines += ["", "## Versions", ""]
    versions = summary.get("versions", {})
    for name, version in versions.items():
        if name != "plugins":
            lines.append(f"- {name}: {version}")
    for plugin, version in versions.get("plugins", {}).items():
        lines.append(f"- plugin {plugin}: {version}")
    lines += ["", "Per-trial figures: `search.png`; every run's files: `trials/`.", ""]
    return "\n".join(lines)


def save_trial_figure(path: Path, summary: Mapping[str, Any]) -> bool:
    """Write :func:`draw_trial_figure` as ``path``; False when matplotlib is not installed."""
    try:
        figure = draw_trial_figure(summary)
    except ImportError:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as temp:
        figure.savefig(temp, dpi=110)
    return True


def draw_trial_figure(summary: Mapping[str, Any]) -> Any:
    """Per-trial centroid error and Hausdorff distance for both planners (a Figure).

    A trial where the object was not found (or the run failed) has no error to plot: it
    is marked by a hollow triangle at the top of the panel, its own legend entry, never as
    a zero error. The dashed line is the thesis's figure (centroid RMSE, Hausdorff mean).
    """
    # A Figure on its own Agg canvas leaves pyplot's global backend alone.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    shapes = list(summary.get("shapes", ("circle", "ellipse")))
    planners = summary.get("planners", {})
    labels = {"search": planners.get("search", "two-phase"),
              "thesis-params": f"{planners.get('thesis-params', 'two-phase')} (Table 3.1)",
              "baseline": f"{planners.get('baseline', 'coverage')} (baseline)"}
    styles = {"search": ("tab:blue", "o"), "thesis-params": ("tab:green", "D"),
              "baseline": ("tab:orange", "s")}
    fig = Figure(figsize=(max(4.5 * len(shapes), 7.5), 6.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, len(shapes), squeeze=False)
    figures = (
        ("centroid_error_m", "centroid error (cm)", "centroid_rmse_m"),
        ("hausdorff_m", "Hausdorff (cm)", "hausdorff_m"),
    )
    for col, shape in enumerate(shapes):
        for row, (key, ylabel, thesis_key) in enumerate(figures):
            ax = axes[row][col]
            if shape in THESIS_TABLE_3_2:
                ax.axhline(THESIS_TABLE_3_2[shape][thesis_key][0] * 100.0, color="grey", ls="--",
                           lw=1.0, label="thesis (Table 3.2)")
            any_missing = False
            for role, (colour, marker) in styles.items():
                runs = [r for r in summary.get("runs", [])
                        if r["shape"] == shape and r["role"] == role]
                xs, ys, missing = [], [], []
                for run in runs:
                    value = _number((run.get("figures") or {}).get(key))
                    if value is None:
                        missing.append(run["index"])
                    else:
                        xs.append(run["index"])
                        ys.append(value * 100.0)
                if xs:
                    ax.plot(xs, ys, ls="none", marker=marker, color=colour, label=labels[role])
                if missing:
                    any_missing = True
                    # x in data, y in axes coordinates: at the top whatever the error range.
                    ax.plot(missing, [0.95] * len(missing), ls="none", marker="v", ms=8,
                            mfc="none", mec=colour, mew=1.5, transform=ax.get_xaxis_transform(),
                            label=f"{labels[role]}: not found / failed")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_xlabel("trial")
            ax.set_ylabel(ylabel)
            # Headroom above the errors for the not-found markers at 95 % of the height.
            ax.set_ylim(0.0, ax.get_ylim()[1] * (1.15 if any_missing else 1.0))
            ax.set_title(shape)
            ax.grid(alpha=0.3)
    # One legend for all panels: "not found" entries may appear in any of them.
    handles: dict[str, Any] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="outside lower center",
                   ncols=min(3, max(1, len(handles))), fontsize=8)
    return fig
