"""The markdown report of ``hapticframe bench perception-real`` (tables per training source)."""

from __future__ import annotations

from typing import Any

__all__ = ["render_real_markdown"]

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
