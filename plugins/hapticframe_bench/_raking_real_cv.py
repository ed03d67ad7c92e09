"""``hapticframe bench raking-real-cv``: how ``raking-real``'s settings were chosen.

On the 80 training trials only (the 20 test trials are not read), grouped k-fold
cross-validation (whole configurations held out: :func:`hapticframe_raking.cross_validate`)
of every combination in :data:`hapticframe_raking.CV_GRID` per input set; the choice is the
lowest distance MAE over held-out steps within :data:`hapticframe_raking.CV_RANGE_MM`. The
report says whether the choice is what :data:`hapticframe_raking.SELECTED` ships.
``--quick``: one input set (4_3-axis) and 2 folds.
"""

from __future__ import annotations

import json
import platform
from collections.abc import Mapping
from typing import Any

import numpy as np

from hapticframe import BenchOptions, atomic_write
from hapticframe_raking import (
    CV_CHOICE,
    CV_GRID,
    CV_RANGE_MM,
    INPUT_SETS,
    SELECTED,
    EstimatorSettings,
    cross_validate,
    load_trials,
)

from ._targets import load_average, load_note

__all__ = ["render_raking_cv_markdown", "run_raking_real_cv"]


def run_raking_real_cv(options: BenchOptions) -> dict[str, Any]:
    """Cross-validate the grid per input set; write ``raking-real-cv.json`` and ``.md``."""
    training = load_trials("training")
    folds = 2 if options.quick else 4
    sets = ["4_3-axis"] if options.quick else list(INPUT_SETS)
    results: dict[str, Any] = {"training_trials": len(training), "folds": folds,
                               "seed": options.seed, "range_mm": CV_RANGE_MM,
                               "grid": {k: list(v) for k, v in CV_GRID.items()},
                               "input_sets": {}}
    for input_set in sets:
        rows = cross_validate(training, EstimatorSettings(input_set=input_set), folds=folds,
                              seed=options.seed)
        best = min(rows, key=lambda r: r[CV_CHOICE])
        results["input_sets"][input_set] = {
            "rows": rows, "chosen": best["settings"],
            "matches_shipped": best["settings"] == SELECTED.get(input_set)}
        options.echo(f"  {input_set:9s} chose {best['settings']} (capped distance MAE "
                     f"{best[CV_CHOICE]:.1f} mm); shipped: "
                     f"{SELECTED.get(input_set)}")
    results["machine"] = {"platform": platform.platform(), "numpy": np.__version__,
                          "load_average_1min": load_average()}
    atomic_write(options.out_dir / "raking-real-cv.json", json.dumps(results, indent=2) + "\n")
    atomic_write(options.out_dir / "raking-real-cv.md", render_raking_cv_markdown(results))
    options.echo(f"wrote {options.out_dir / 'raking-real-cv.md'} and raking-real-cv.json")
    return {f"{s}_matches_shipped": e["matches_shipped"]
            for s, e in results["input_sets"].items()}


def render_raking_cv_markdown(results: Mapping[str, Any]) -> str:
    """One table per input set: every combination's held-out scores, the choice marked."""
    lines = ["# Real raking data: settings chosen by cross-validation on the training trials",
             "",
             f"{results['training_trials']} training trials, {results['folds']} folds holding "
             f"out whole configurations, seed {results['seed']}; the choice: lowest distance "
             f"MAE over held-out steps against the true distance capped at "
             f"{results['range_mm']:.0f} mm (the map's range). "
             f"{load_note(results['machine']['load_average_1min'])}.", ""]
    for input_set, e in results["input_sets"].items():
        lines += [f"## {input_set}", "",
                  "| distance cap (mm) | steps left out | window | distance MAE, capped truth "
                  "(mm) | in range only (mm) | true distance (mm) | direction acc. | depth acc. "
                  "| |", "|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(e["rows"], key=lambda r: r[CV_CHOICE]):
            s = r["settings"]
            mark = "chosen" if s == e["chosen"] else ""
            lines.append(f"| {s['range_mm']} | {s['skip_first_steps']} | {s['window_steps']} "
                         f"| {r[CV_CHOICE]:.1f} | {r['distance_mae_in_range_mm']:.1f} "
                         f"| {r['distance_mae_mm']:.1f} "
                         f"| {r['direction_accuracy']:.3f} | {r['depth_accuracy']:.3f} "
                         f"| {mark} |")
        same = "the same" if e["matches_shipped"] else "not the same"
        lines += ["", f"Shipped in `SELECTED`: {same}.", ""]
    return "\n".join(lines)
