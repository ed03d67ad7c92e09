"""``hapticframe bench search-physics``: Table 3.2 in sand our models did not write (issue 29).

The protocol of ``bench search`` (:func:`~hapticframe_bench._search.run_suite`: the same
placements, seeds and figures) run in the ``mpm-sand`` world, whose forces come from NVIDIA
Newton's material-point solver through a response library, with three configurations of the
two-phase planner, beside the analytic ``sandbox`` on the same placements:

(a) today's defaults; (b) the models calibrated in that world (below); (c) the dissertation's
Table 3.1 configuration (role ``thesis-params``).

Calibration, as a lab would do it from its own rig: one search per shape at a held-out
placement (another seed than the suite's) is recorded in the world with
``run.halt_on_interaction: false``, so that every movement runs through free sand, the
jamming ahead of the object and contact; then

- the jamming classifier's thresholds are fitted by ``hapticframe train`` on each recording
  (the ``calibrate-physics.yaml`` experiment: the world's ground truth as labels, the
  jamming force threshold floored at the free-sand drag, ``calibration_force_floor:
  free-drag``), the larger of the two fits per threshold kept;
- the failure-zone kernel's rupture distance, sector angle and depth schedule are fitted
  from the same recordings (``python -m hapticframe_failure_zone.fit_runs``:
  :func:`hapticframe_failure_zone.fit_failure_zone`).

Outputs in ``options.out_dir``: ``sandbox/``, ``mpm/`` and ``mpm-calibrated/`` (each a
``bench search`` report with its trial runs), ``calibration/`` (the recordings, the trained
thresholds, ``failure-zone-fit.json``), and ``search-physics.json`` / ``search-physics.md``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

import hapticframe
from hapticframe import BenchOptions, atomic_write

from ._placements import SHAPES, draw_placements
from ._report import THESIS_TABLE_3_2
from ._search import SEARCH_PLANNER, THESIS_ROLE, run_suite, trials_for
from ._template import REGION_HEIGHT_M, REGION_WIDTH_M, search_experiment

__all__ = ["calibrate_in_world", "render_physics_markdown", "run_search_physics"]

WORLD = "mpm-sand"
WORLD_OVERRIDE = f"robots[0].type={WORLD}"
#: Placements per shape of ``--quick``.
QUICK_TRIALS = 2
#: Seed offset of the calibration's placements: never one the suite scores.
CALIBRATION_SEED_OFFSET = 1000
#: The analytic sandbox's (and the kernel's) defaults, for the parameter table.
SANDBOX_DEFAULTS = {
    "jamming_force_n": 6.0,
    "jamming_rate_n_per_s": 27.0,
    "contact_force_n": 30.0,
    "contact_rate_n_per_s": 70.0,
    "shear_band_angle_deg": 31.5,  # the scene's Arthur angle, phi 42 deg, psi 12 deg
    "sector_half_angle_deg": 50.0,
    "initial_depth_m": 0.044,
    "depth_decrement_m": 0.01,
    "depth_decrement_ratio": 0.5,
}
#: Table 3.1 (Jia 2022): rupture distance at the four depths, eta at n = 0, the schedule.
TABLE_3_1: dict[str, Any] = {
    "rupture_distance_m": {0.044: 0.072, 0.034: 0.055, 0.029: 0.047, 0.0265: 0.043},
    "sector_half_angle_deg": 50.0,
    "initial_depth_m": 0.044,
    "depth_decrement_m": 0.01,
    "depth_decrement_ratio": 0.5,
}
_THRESHOLDS = ("jamming_force_n", "jamming_rate_n_per_s", "contact_force_n",
               "contact_rate_n_per_s")


def _calibration_experiment(recorded: Path) -> dict[str, Any]:
    """``examples/calibrate-physics.yaml``'s experiment, pointed at one recording."""
    return {
        "schema_version": 1,
        "name": "calibrate-physics",
        "description": "Jamming thresholds from a recording in the mpm-sand world.",
        "seed": 7,
        "sensors": [{
            "id": "wrist", "type": "trace-recording",
            "config": {"path": str(recorded), "component": "wrist", "robot": "arm",
                       "labels": str(recorded), "labels_key": "state",
                       "label_channel": "label"},
        }],
        "classifiers": [{"id": "jamming", "type": "force-rate-jamming", "inputs": ["wrist"],
                         "config": {"calibration_force_floor": "free-drag"}}],
        "run": {"label_channel": "label"},
    }


def _record(objects: Sequence[Mapping[str, Any]], seed: int, run_dir: Path) -> None:
    data = search_experiment(objects, SEARCH_PLANNER, seed, f"record-{run_dir.name}")
    data["robots"][0]["type"] = WORLD
    data.setdefault("run", {}).update({"halt_on_interaction": False, "figures": False})
    experiment = hapticframe.validate_with_overrides(data, (), source=f"<record {run_dir}>")
    try:
        hapticframe.run_experiment(experiment, run_dir, overwrite=True, echo=lambda _line: None)
    except hapticframe.RunInconclusive:
        # A calibration recording rakes on through contact on purpose, so its movements end
        # at the force limit: no search result, but the recording (kept) is what is wanted.
        pass


def _train(recorded: Path, out: Path) -> dict[str, float]:
    """Run ``hapticframe train`` on one recording; the four thresholds it saved."""
    spec = out.with_suffix(".yaml")
    atomic_write(spec, yaml.safe_dump(_calibration_experiment(recorded), sort_keys=False))
    done = subprocess.run(
        [sys.executable, "-m", "hapticframe", "train", str(spec), "--out", str(out),
         "--overwrite"],
        capture_output=True, text=True, check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"hapticframe train {spec} failed ({done.returncode}): "
                           f"{done.stderr.strip()[-2000:]}")
    saved = json.loads((out / "jamming" / "thresholds.json").read_text())
    return {k: float(saved["thresholds"][k]) for k in _THRESHOLDS}


def calibrate_in_world(out_dir: Path, seed: int, shapes: Sequence[str] = SHAPES,
                       echo: Any = print) -> dict[str, Any]:
    """Record one held-out search per shape in the world; fit the thresholds and the kernel.

    Returns the calibration's summary: per recording the thresholds ``hapticframe train``
    fitted, the combined thresholds (the largest per threshold: every recording's free drag
    stays below them), the failure-zone fit over all recordings, and the ``--set`` texts
    that apply both to a search.
    """
    from hapticframe_failure_zone.fit_runs import fit_recorded_runs

    out_dir.mkdir(parents=True, exist_ok=True)
    placements = draw_placements(
        np.random.default_rng(seed + CALIBRATION_SEED_OFFSET), 1,
        (0.0, REGION_WIDTH_M, 0.0, REGION_HEIGHT_M), tuple(shapes))
    fits: dict[str, dict[str, float]] = {}
    recorded_runs = []
    for shape in shapes:
        placement = placements[shape][0]
        recorded = out_dir / f"recorded-{shape}"
        echo(f"calibration: recording a search for a {shape} in {WORLD} into {recorded}")
        _record(placement.scene_objects(), seed + CALIBRATION_SEED_OFFSET, recorded)
        fits[shape] = _train(recorded, out_dir / f"jamming-{shape}")
        recorded_runs.append(recorded)
    combined = {k: max(f[k] for f in fits.values()) for k in _THRESHOLDS}
    combined["contact_force_n"] = max(combined["contact_force_n"], combined["jamming_force_n"])
    combined["contact_rate_n_per_s"] = max(combined["contact_rate_n_per_s"],
                                           combined["jamming_rate_n_per_s"])
    kernel = fit_recorded_runs(recorded_runs)
    atomic_write(out_dir / "failure-zone-fit.json",
                 json.dumps(kernel.as_dict(), indent=2) + "\n")
    overrides = [f"jamming.{k}={v!r}" for k, v in combined.items()]
    overrides += [f"failure-zone.{k}={v!r}" for k, v in kernel.config_overrides().items()]
    return {"recordings": {s: str(out_dir / f"recorded-{s}") for s in shapes},
            "placements": {s: placements[s][0].to_dict() for s in shapes},
            "thresholds_per_recording": fits, "thresholds": combined,
            "failure_zone": kernel.as_dict(), "overrides": overrides}


def _row(group: Mapping[str, Any] | None) -> dict[str, Any]:
    group = group or {}

    def stat(key: str, scale: float = 1.0) -> tuple[float | None, float | None]:
        s = group.get(key)
        if not isinstance(s, Mapping) or s.get("mean") is None:
            return None, None
        return s["mean"] * scale, (s.get("std") or 0.0) * scale

    rmse = group.get("centroid_rmse_m")
    return {"ems_phase1": stat("ems_phase1"), "ems_phase2": stat("ems_phase2"),
            "object_interactions": stat("object_interactions"),
            "centroid_rmse_cm": None if rmse is None else 100 * rmse,
            "hausdorff_cm": stat("hausdorff_m", 100.0),
            "found": group.get("found"), "completed": group.get("completed")}


def _fmt(value: tuple[float | None, float | None] | float | None, unit: str = "") -> str:
    if isinstance(value, tuple):
        mean, std = value
        return "–" if mean is None else f"{mean:.1f} ± {std:.1f}{unit}"
    return "–" if value is None else f"{value:.1f}{unit}"


def _parameter_rows(calibration: Mapping[str, Any]) -> list[list[str]]:
    kernel = calibration["failure_zone"]
    thresholds = calibration["thresholds"]
    rows = []
    for depth, thesis_r in TABLE_3_1["rupture_distance_m"].items():
        sandbox_r = depth / math.tan(math.radians(SANDBOX_DEFAULTS["shear_band_angle_deg"]))
        rows.append([f"rupture distance at {100 * depth:.2f} cm depth",
                     f"{100 * kernel['rupture_ratio'] * depth:.1f} cm",
                     f"{100 * thesis_r:.1f} cm", f"{100 * sandbox_r:.1f} cm"])
    rows.append(["shear-band angle β", f"{kernel['shear_band_angle_deg']:.1f}°", "–",
                 f"{SANDBOX_DEFAULTS['shear_band_angle_deg']:.1f}°"])
    rows.append(["sector half-angle η (n = 0)", f"{kernel['sector_half_angle_deg']:.1f}°",
                 f"{TABLE_3_1['sector_half_angle_deg']:.0f}° (+7° per pair)",
                 f"{SANDBOX_DEFAULTS['sector_half_angle_deg']:.0f}° (+7° per pair)"])
    for key, label in (("initial_depth_m", "initial depth"),
                       ("depth_decrement_m", "first depth decrement")):
        rows.append([label, f"{100 * kernel[key]:.2f} cm", f"{100 * TABLE_3_1[key]:.2f} cm",
                     f"{100 * SANDBOX_DEFAULTS[key]:.2f} cm"])
    rows.append(["later decrements (ratio)", f"{kernel['depth_decrement_ratio']:.2f}",
                 f"{TABLE_3_1['depth_decrement_ratio']:.2f}",
                 f"{SANDBOX_DEFAULTS['depth_decrement_ratio']:.2f}"])
    for key in _THRESHOLDS:
        unit = "N/s" if "rate" in key else "N"
        rows.append([f"`{key}`", f"{thresholds[key]:.2f} {unit}", "–",
                     f"{SANDBOX_DEFAULTS[key]:.1f} {unit}"])
    return rows


#: (world, configuration label, key in the summary's ``results``).
CONFIGURATIONS = (
    ("analytic sandbox", "(a) defaults", "sandbox_defaults"),
    ("analytic sandbox", "(c) Table 3.1", "sandbox_thesis"),
    (WORLD, "(a) defaults", "mpm_defaults"),
    (WORLD, "(b) calibrated in the world", "mpm_calibrated"),
    (WORLD, "(c) Table 3.1", "mpm_thesis"),
)


def render_physics_markdown(summary: Mapping[str, Any]) -> str:
    """The Markdown report (``search-physics.md``) of a :func:`run_search_physics` summary."""
    lines = ["# Haptic search in sand our models did not write (issue 29)", "",
             f"Command: `{summary.get('command', '')}`", "",
             f"{summary['trials']} placement(s) per shape, seed {summary['seed']}, the same "
             "placements in both worlds; wall time "
             f"{_fmt(summary.get('wall_time_s'), ' s')}.", "",
             "| shape | world | configuration | phase-1 EMs | phase-2 EMs | object interactions "
             "| centroid RMSE | Hausdorff | found |",
             "|---|---|---|---|---|---|---|---|---|"]
    for shape in summary["shapes"]:
        thesis = THESIS_TABLE_3_2.get(shape)
        if thesis is not None:
            lines.append(
                f"| {shape} | thesis (Jia 2022) | | {thesis['ems_phase1'][0]} ± "
                f"{thesis['ems_phase1'][1]} | {thesis['ems_phase2'][0]} ± "
                f"{thesis['ems_phase2'][1]} | – | {100 * thesis['centroid_rmse_m'][0]:.1f} cm | "
                f"{100 * thesis['hausdorff_m'][0]:.1f} ± {100 * thesis['hausdorff_m'][1]:.1f} cm "
                "| – |")
        for world, label, key in CONFIGURATIONS:
            row = summary["results"][key][shape]
            found = ("–" if row["completed"] is None
                     else f"{row['found']}/{row['completed']}")
            lines.append(
                f"| {shape} | {world} | {label} | {_fmt(tuple(row['ems_phase1']))} | "
                f"{_fmt(tuple(row['ems_phase2']))} | {_fmt(tuple(row['object_interactions']))} | "
                f"{_fmt(row['centroid_rmse_cm'], ' cm')} | "
                f"{_fmt(tuple(row['hausdorff_cm']), ' cm')} | {found} |")
    lines += ["", "Lengths are over the runs that found the object; interactions over every "
              "completed run.", "", "## Calibrated in the world, against Table 3.1 and the "
              "analytic sandbox's defaults", "",
              "| parameter | calibrated in mpm-sand | Table 3.1 (Jia 2022) | sandbox defaults |",
              "|---|---|---|---|"]
    lines += ["| " + " | ".join(r) + " |" for r in _parameter_rows(summary["calibration"])]
    kernel = summary["calibration"]["failure_zone"]
    lines += ["", f"Jamming onsets read: {len(kernel['onset_distance_m'])} movements; "
              "thresholds per recording: "
              + "; ".join(f"{s}: " + ", ".join(f"{v:.2f}" for v in t.values())
                          for s, t in summary["calibration"]["thresholds_per_recording"].items())
              + ".", ""]
    return "\n".join(lines)


def run_search_physics(options: BenchOptions) -> dict[str, Any]:
    """``hapticframe bench search-physics`` (see the module docstring).

    ``--trials`` placements per shape (default 25, ``--quick`` 2), ``--seed``, ``--workers``,
    and ``--set`` texts applied to every run (after the world's own).
    """
    started = time.perf_counter()
    trials = options.trials or (QUICK_TRIALS if options.quick else trials_for(options))
    out = Path(options.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    calibration = calibrate_in_world(out / "calibration", options.seed, echo=options.echo)
    both = {"search": SEARCH_PLANNER, THESIS_ROLE: SEARCH_PLANNER}

    def suite(sub: str, overrides: Sequence[str], planners: Mapping[str, str]) -> dict[str, Any]:
        opts = dataclasses.replace(options, out_dir=out / sub, trials=trials,
                                   overrides=(*overrides, *options.overrides))
        options.echo(f"search-physics: {sub}")
        return run_suite(opts, planners=planners)

    sandbox = suite("sandbox", (), both)
    mpm = suite("mpm", (WORLD_OVERRIDE,), both)
    calibrated = suite("mpm-calibrated", (WORLD_OVERRIDE, *calibration["overrides"]),
                       {"search": SEARCH_PLANNER})
    shapes = list(SHAPES)
    results = {
        "sandbox_defaults": {s: _row(sandbox.get(s)) for s in shapes},
        "sandbox_thesis": {s: _row(sandbox.get("thesis_params", {}).get(s)) for s in shapes},
        "mpm_defaults": {s: _row(mpm.get(s)) for s in shapes},
        "mpm_calibrated": {s: _row(calibrated.get(s)) for s in shapes},
        "mpm_thesis": {s: _row(mpm.get("thesis_params", {}).get(s)) for s in shapes},
    }
    command = f"hapticframe bench search-physics --trials {trials} --seed {options.seed}"
    summary: dict[str, Any] = {
        "command": command, "trials": trials, "seed": options.seed, "shapes": shapes,
        "world": WORLD, "results": results, "calibration": calibration,
        "reports": {"sandbox": "sandbox/search.json", "mpm": "mpm/search.json",
                    "mpm_calibrated": "mpm-calibrated/search.json"},
        "wall_time_s": time.perf_counter() - started,
    }
    atomic_write(out / "search-physics.json",
                 json.dumps(summary, indent=2, allow_nan=False, default=str) + "\n")
    atomic_write(out / "search-physics.md", render_physics_markdown(summary))
    options.echo(f"search-physics done in {summary['wall_time_s']:.1f} s: "
                 f"{out / 'search-physics.md'}")
    return summary
