"""``hapticframe bench raking-map``: where the real test trials place the buried object.

For each of the 20 real test trials (``hapticframe_raking``), the tool's recorded positions
and its tactile forces give observations by two sensor models, and each trial's object
position estimate is the weighted mean of its object observations (target 1):

- ``distance-estimate``: the shipped ``raking-estimator`` (4_3-axis) streamed over the
  trial, each sample placed at the estimated distance, in the direction classes' bearings,
  weighted by certainty (:func:`hapticframe_raking.place_observations`; every sample, no
  consistency check over travel, no points behind the outline point: see
  :func:`run_raking_map`). The bearings are
  calibrated on the 80 training trials: per direction class, the median bearing of the
  labels' object point from the tool at the trial's last step.
- the failure zone's rule: the ``force-rate-jamming`` classifier (calibrated on the training
  trials as in ``raking-jamming``) flags samples; each flagged sample places the object at
  one fixed distance straight ahead, weighted by its non-free probability. The distance is
  calibrated on the training trials too: the median labelled distance of their flagged
  samples (``FIXED_DISTANCE_M`` only where none is flagged).

Each model's observations, with the tool's path as free observations (the tool went
through there), also build a Bayesian Hilbert Map per trial (a 10 x 12 cm region around the
rake's end, hinges every 1 cm); the map's most probable point is its object estimate.

The truth is the point the trial's distance labels are measured to
(:func:`hapticframe_raking.object_point`). Scores per trial and model: the error of the
observations' weighted mean (2-D, along the rake and across it), whether the model placed
anything, and the error of the map's most probable point.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, RegionConfig, atomic_write
from hapticframe.kinds import BuildContext, Observations
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_raking import (
    DistanceEstimateConfig,
    RakingModel,
    RakingTrial,
    load_trials,
    object_point,
    place_observations,
    pretrained_model_dir,
    select_inputs,
)

from ._raking_jamming import JAMMING_MM, jamming_labels, trial_batch
from ._targets import load_average, load_note

__all__ = ["FIXED_DISTANCE_M", "calibrated_bearings_deg", "run_raking_map", "trial_headings"]

FIXED_DISTANCE_M = 0.03


def trial_headings(trial: RakingTrial) -> np.ndarray:
    """The direction of travel at each step (the trial's overall direction: a straight rake)."""
    travel = trial.position_m[-1, :2] - trial.position_m[0, :2]
    return np.full(len(trial), float(np.arctan2(travel[1], travel[0])))


def calibrated_bearings_deg(trials: Sequence[RakingTrial]) -> tuple[float, float, float]:
    """Per direction class, the median bearing of the object point from the tool's last
    position, relative to the heading (degrees, counter-clockwise)."""
    by_class: dict[int, list[float]] = {0: [], 1: [], 2: []}
    for trial in trials:
        to_object = object_point(trial) - trial.position_m[-1, :2]
        angle = np.arctan2(to_object[1], to_object[0]) - trial_headings(trial)[-1]
        by_class[int(trial.direction[0])].append(
            float(np.degrees(np.arctan2(np.sin(angle), np.cos(angle)))))
    return tuple(float(np.median(v)) if v else 0.0 for v in by_class.values())  # type: ignore[return-value]


def _point(obs: Observations) -> np.ndarray | None:
    positive = (obs.targets > 0.5) & (obs.weights > 0)
    if not positive.any():
        return None
    w = obs.weights[positive]
    return np.asarray((obs.points_m[positive] * w[:, None]).sum(axis=0) / w.sum())


def _errors(estimate: np.ndarray | None, truth: np.ndarray, heading: float
            ) -> dict[str, float | None]:
    if estimate is None:
        return {"error_m": None, "along_m": None, "across_m": None}
    delta = estimate - truth
    along = float(delta[0] * np.cos(heading) + delta[1] * np.sin(heading))
    across = float(-delta[0] * np.sin(heading) + delta[1] * np.cos(heading))
    return {"error_m": float(np.hypot(*delta)), "along_m": along, "across_m": across}


#: A map whose largest occupancy mean is below this found no object.
FOUND_LEVEL = 0.5


def trial_map(trial: RakingTrial, obs: Observations
              ) -> tuple[BayesianHilbertMap, np.ndarray, float]:
    """A map of one trial from ``obs`` and the tool's path (free), its most probable point
    and the occupancy mean there."""
    path = trial.position_m[:, :2]
    x0, y_end = float(path[:, 0].mean()), float(path[-1, 1])
    region = RegionConfig(x_min_m=x0 - 0.05, x_max_m=x0 + 0.05, y_min_m=y_end - 0.06,
                          y_max_m=y_end + 0.06)
    bhm = BayesianHilbertMap(
        BayesianHilbertMapConfig(region=region, hinge_spacing_m=0.01,
                                 length_scale_free_m=0.0066),
        BuildContext("map", np.random.default_rng(0)))
    bhm.update(Observations.concatenate([obs, Observations(path, np.zeros(len(path)))]))
    xs, ys, mean, _ = bhm.probability_grid(0.002)
    row, col = np.unravel_index(int(np.argmax(mean)), mean.shape)
    return bhm, np.array([xs[col], ys[row]]), float(mean[row, col])


def _map_error(trial: RakingTrial, obs: Observations, truth: np.ndarray) -> float | None:
    _, best, level = trial_map(trial, obs)
    return float(np.hypot(*(best - truth))) if level >= FOUND_LEVEL else None


def run_raking_map(options: BenchOptions) -> dict[str, Any]:
    """Score both sensor models' object positions on the 20 test trials."""
    from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig

    training, testing = load_trials("training"), load_trials("testing")
    bearings = calibrated_bearings_deg(training)
    # Three defaults of the sensor model are for a search's 100 Hz stream and a map, not
    # for scoring where a 10 Hz recording places the outline point: the real estimate
    # falls more slowly than the tool approaches (it does not follow the travel, so the
    # consistency check leaves 6 of the 20 trials unplaced), the points behind the outline
    # point would move the scored mean by half their depth, and samples 1.3 mm apart are
    # each a report.
    config = DistanceEstimateConfig(direction_bearings_deg=bearings, consistency_travel_m=0.0,
                                    object_depth_m=0.0, report_spacing_m=0.0)
    model = RakingModel.load(pretrained_model_dir())
    jamming = ForceRateJammingClassifier(
        ForceRateJammingConfig(force_channel="taxel_force", sample_rate_hz=10.0, cutoff_hz=2.0,
                               restart_after_gap_s=0.5),
        BuildContext("jamming", np.random.default_rng(0)))
    jamming.fit([trial_batch(t) for t in training], [jamming_labels(t) for t in training])
    flagged_mm = np.concatenate([
        t.distance_mm[jamming.predict_proba(trial_batch(t)).probabilities[:, 0] < 0.5]
        for t in training])
    fixed_m = float(np.median(flagged_mm)) / 1e3 if flagged_mm.size else FIXED_DISTANCE_M
    rows, drawn = [], None
    for trial in testing:
        truth = object_point(trial)
        heading = trial_headings(trial)
        positions = trial.position_m[:, :2]
        est = model.estimate_trial(select_inputs(trial.force, "4_3-axis"))
        ours = place_observations(positions, heading, est, config)
        interaction = 1.0 - jamming.predict_proba(trial_batch(trial)).probabilities[:, 0]
        flagged = interaction > 0.5
        fixed_points = positions[flagged] + fixed_m * np.column_stack(
            [np.cos(heading[flagged]), np.sin(heading[flagged])])
        fixed = Observations(fixed_points, np.ones(len(fixed_points)), interaction[flagged])
        row = {"trial": trial.name, "truth_m": truth.tolist(),
               "ours": _errors(_point(ours), truth, float(heading[0])),
               "fixed": _errors(_point(fixed), truth, float(heading[0])),
               "ours_map_error_m": _map_error(trial, ours, truth),
               "fixed_map_error_m": _map_error(trial, fixed, truth),
               "ours_points": int((ours.targets > 0.5).sum()),
               "fixed_points": len(fixed)}
        rows.append(row)
        if drawn is None and len(fixed):
            drawn = (trial, truth, ours, fixed)
    summary = {}
    for who in ("ours", "fixed"):
        errors = [r[who]["error_m"] for r in rows if r[who]["error_m"] is not None]
        along = [abs(r[who]["along_m"]) for r in rows if r[who]["along_m"] is not None]
        across = [abs(r[who]["across_m"]) for r in rows if r[who]["across_m"] is not None]
        summary[who] = {
            "trials_placed": len(errors),
            "error_mm_median": 1e3 * float(np.median(errors)) if errors else None,
            "error_mm_mean": 1e3 * float(np.mean(errors)) if errors else None,
            "error_mm_max": 1e3 * float(np.max(errors)) if errors else None,
            "along_mm_median": 1e3 * float(np.median(along)) if along else None,
            "across_mm_median": 1e3 * float(np.median(across)) if across else None,
            "map_found": len(mapped := [r[f"{who}_map_error_m"] for r in rows
                                        if r[f"{who}_map_error_m"] is not None]),
            "map_error_mm_median": 1e3 * float(np.median(mapped)) if mapped else None,
            "map_error_mm_max": 1e3 * float(np.max(mapped)) if mapped else None}
    results: dict[str, Any] = {"bearings_deg": list(bearings), "fixed_distance_m": fixed_m,
               "jamming_label_mm": JAMMING_MM, "summary": summary, "per_trial": rows,
               "machine": {"load_average_1min": load_average()}}
    atomic_write(options.out_dir / "raking-map.json", json.dumps(results, indent=2) + "\n")
    atomic_write(options.out_dir / "raking-map.md", _markdown(results))
    if drawn is not None:
        _figure(options.out_dir / "raking-map.png", *drawn)
    for who, label in (("ours", "distance-estimate"), ("fixed", "fixed distance (jamming)")):
        s = summary[who]
        options.echo(f"{label}: placed in {s['trials_placed']}/{len(rows)} trials; error "
                     f"median {_mm(s['error_mm_median'])} (along {_mm(s['along_mm_median'])}, "
                     f"across {_mm(s['across_mm_median'])}); map found it in "
                     f"{s['map_found']}/{len(rows)}, most probable point off by median "
                     f"{_mm(s['map_error_mm_median'])}")
    options.echo(load_note(results["machine"]["load_average_1min"]))
    return {who: summary[who]["error_mm_median"] for who in summary}


def _mm(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f} mm"


def _markdown(results: Mapping[str, Any]) -> str:
    lines = ["# Where the real test trials place the object", "",
             f"Direction bearings (calibrated on the training trials): "
             f"{', '.join(f'{b:.1f}°' for b in results['bearings_deg'])}; fixed distance "
             f"{1e3 * results['fixed_distance_m']:.0f} mm.", "",
             "| sensor model | trials placed | error median (mm) | mean | max | "
             "along the rake, median | across, median | map: found | map: error median | "
             "map: max |", "|---|---|---|---|---|---|---|---|---|---|"]
    for who, label in (("ours", "distance-estimate"), ("fixed", "fixed distance (jamming)")):
        s = results["summary"][who]
        lines.append(f"| {label} | {s['trials_placed']} | {_mm(s['error_mm_median'])} | "
                     f"{_mm(s['error_mm_mean'])} | {_mm(s['error_mm_max'])} | "
                     f"{_mm(s['along_mm_median'])} | {_mm(s['across_mm_median'])} | "
                     f"{s['map_found']} | {_mm(s['map_error_mm_median'])} | "
                     f"{_mm(s['map_error_mm_max'])} |")
    return "\n".join(lines) + "\n"


def _figure(path: Path, trial: RakingTrial, truth: np.ndarray, ours: Observations,
            fixed: Observations) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(1, 2, figsize=(9, 6), sharey=True)
    p = trial.position_m
    for ax, obs, title in ((axes[0], ours, "distance-estimate"),
                           (axes[1], fixed, "fixed distance (jamming rule)")):
        bhm, best, _ = trial_map(trial, obs)
        xs, ys, mean, _ = bhm.probability_grid(0.002)
        image = ax.pcolormesh(1e3 * xs, 1e3 * ys, mean, vmin=0, vmax=1, cmap="viridis",
                              shading="auto")
        ax.plot(1e3 * p[:, 0], 1e3 * p[:, 1], "w-", lw=1.5, label="tool path (recorded)")
        obj = obs.targets > 0.5
        ax.scatter(1e3 * obs.points_m[obj, 0], 1e3 * obs.points_m[obj, 1], s=6, c="tab:red",
                   label="object observations")
        ax.plot(1e3 * truth[0], 1e3 * truth[1], "*", ms=15, c="tab:orange", mec="k",
                label="object point of the labels (truth)")
        ax.plot(1e3 * best[0], 1e3 * best[1], "P", ms=11, c="white", mec="k",
                label="map's most probable point")
        ax.set_title(f"{title}, test trial {trial.name}\n(found where the mean ≥ "
                     f"{FOUND_LEVEL:g})", fontsize=9)
        ax.set_xlabel("x (mm, robot frame)")
        ax.set_xlim(1e3 * xs[0], 1e3 * xs[-1])
        ax.set_ylim(1e3 * ys[0], 1e3 * ys[-1])
        ax.set_aspect("equal")
        ax.legend(fontsize=6, loc="upper right")
    axes[0].set_ylabel("y (mm, robot frame)")
    fig.colorbar(image, ax=axes, label="occupancy probability (map mean)", shrink=0.8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True
