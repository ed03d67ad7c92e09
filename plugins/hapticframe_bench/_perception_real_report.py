"""The markdown report of ``hapticframe bench perception-real`` (tables per training source)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["render_real_markdown", "save_real_figure"]

_SOURCES = {
    "synthetic": "(a) trained on synthetic granular rakes only (uncalibrated generator)",
    "calibrated": "(a') trained on synthetic press trials from the calibrated generator only",
    "calibrated-loo": "(a'') trained on synthetic press trials only, the generator calibrated "
    "on the other objects' trials (leave one object out)",
    "real-loo": "(b) trained on the real trials of the other objects (leave one object out)",
}


def _cell(value: Any, digits: int = 3) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _table(rows: list[dict[str, Any]], objects: list[str], key: str, digits: int) -> list[str]:
    lines = ["| model | inputs | " + " | ".join(objects) + " | mean |",
             "|---|---|" + "---|" * (len(objects) + 1)]
    combos: dict[tuple[str, str], dict[str, dict[str, Any]]] = {}
    for r in rows:
        combos.setdefault((r["model"], r["inputs"]), {})[r["object"]] = r
    for (model, inputs), by_object in combos.items():
        values = [by_object.get(o, {}).get(key) for o in objects]
        known = [v for v in values if v is not None]
        mean = sum(known) / len(known) if known else None
        lines.append(f"| {model} | {inputs} | "
                     + " | ".join(_cell(v, digits) for v in values) + f" | {_cell(mean, digits)} |")
    return lines


def render_real_markdown(result: dict[str, Any]) -> str:
    """Per source: balanced accuracy, recall at the chosen specificity and first-contact
    delay per object, against the reference derived from pdc."""
    ref = result["reference"]
    objects = result["objects"]
    rows = result["results"]
    spec = rows[0]["specificity"] if rows else 0.95
    missed = sum(r["missed_contacts"] for r in rows)
    lines = [
        "# Contact detection on real BioTac trials (Penn BOLT)",
        "",
        f"Reference: **{ref['name']}** — {ref['rule']} (rest_frames {ref['rest_frames']}, "
        f"on {ref['on_counts']:g}, off {ref['off_counts']:g} counts). Because it is read off "
        "pdc, every model is also trained and scored **without pdc** (pac and electrodes "
        "only).",
        "",
        f"{len(objects)} objects, {result['recordings']} recordings (trials × 2 fingers), "
        f"{result['frames']:,} frames, {100 * result['contact_fraction']:.1f} % contact by "
        f"the reference; seed {result['seed']}; command `{result['command']}`; "
        f"{result['machine']['cpus']} CPUs, {result['machine']['workers']} workers, load "
        f"{result['machine']['load_average_1min_start']:.1f} at start, "
        f"{result['machine']['load_average_1min_end']:.1f} at end; "
        f"{result['timing_s']['total_wall']:.0f} s.",
        "",
    ]
    for source, title in _SOURCES.items():
        chosen = [r for r in rows if r["source"] == source]
        if not chosen:
            continue
        lines += [f"## {title}", "", "Balanced accuracy:", ""]
        lines += _table(chosen, objects, "balanced_accuracy", 3)
        lines += ["", f"Recall at specificity {spec:.2f}:", ""]
        lines += _table(chosen, objects, "recall_at_specificity", 3)
        lines += ["", "First-contact delay (s, median over recordings; – none read):", ""]
        lines += _table(chosen, objects, "first_contact_delay_s", 2)
        lines.append("")
    lines += [f"Recordings whose contact was never read, over all cells: {missed}.", ""]
    if result.get("calibration"):
        lines += ["Calibration trials (never scored): "
                  + "; ".join(f"{o}: {', '.join(v)}"
                              for o, v in result["calibration"]["trials"].items()), ""]
    return "\n".join(lines)


def save_real_figure(result: dict[str, Any], path: Path) -> Path | None:
    """Balanced accuracy per object, one panel per model, a bar per training source, solid
    with pdc and hatched without; the dashed line is the goal (0.9). None without
    matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    rows = result["results"]
    objects = result["objects"]
    sources = [s for s in _SOURCES if any(r["source"] == s for r in rows)]
    models = list(dict.fromkeys(r["model"] for r in rows))
    if not rows or not sources:
        return None
    colours = {"synthetic": "tab:red", "calibrated": "tab:blue", "calibrated-loo": "tab:cyan",
               "real-loo": "black"}
    fig, axes = plt.subplots(len(models), 1, figsize=(12, 3.2 * len(models)), squeeze=False)
    width = 0.8 / (2 * len(sources))
    for ax, model in zip(axes[:, 0], models, strict=True):
        for i, source in enumerate(sources):
            for j, inputs in enumerate(("with pdc", "without pdc")):
                values = []
                for obj in objects:
                    found = [r["balanced_accuracy"] for r in rows if r["source"] == source
                             and r["model"] == model and r["inputs"] == inputs
                             and r["object"] == obj]
                    values.append(found[0] if found else 0.0)
                offset = (2 * i + j - len(sources) + 0.5) * width
                ax.bar([k + offset for k in range(len(objects))], values, width,
                       color=colours.get(source, "grey"), hatch="//" if j else None,
                       edgecolor="white" if j else None,
                       label=f"{source}, {inputs}")
        ax.axhline(0.9, color="grey", ls="--", lw=1, label="goal 0.9")
        lowest = min(r["balanced_accuracy"] for r in rows)
        ax.set_ylim(min(0.4, lowest - 0.05), 1.0)
        ax.set_xticks(range(len(objects)), [o.replace("_", " ") for o in objects])
        ax.set_ylabel("balanced accuracy")
        ax.set_title(f"{model}: contact against the reference derived from pdc")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=8)
    fig.suptitle(f"Real BioTac trials (Penn BOLT), seed {result['seed']}")
    fig.tight_layout(rect=(0.0, 0.06, 1.0, 1.0))
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
