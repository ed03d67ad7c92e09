"""``hapticframe bench raking-jamming``: the force/force-rate jamming rule on real raking data.

The dissertation's premise: force and force rate rise ahead of contact, as the sand between
tool and object jams. The real trials of Chen, Versace & Jamone (``hapticframe_raking``)
are labelled with the distance to the object at every step, so the premise can be checked
and the ``force-rate-jamming`` classifier calibrated and scored on them.

- Force: the magnitude of the 12 taxel components (4 taxels x, y, z) the classifier reads
  from ``taxel_force``, in the authors' normalized units (0..1 per component, not newtons:
  the thresholds are in the same units). Sample rate: the layout's nominal 10 Hz (assumed).
- Labels for calibration: jamming (1) where the labelled distance is at most
  ``JAMMING_MM``, free (0) beyond; the trials end before contact (10-17 mm), so there is no
  contact class. The classifier is fitted on the 80 training trials with its own ``fit``
  (what ``hapticframe train`` calls), low-pass cutoff 2 Hz (below the 5 Hz Nyquist rate).
- On the 20 test trials: the distance at which each trial is first flagged (any class but
  free), and false alarms while the object is far (distance above ``FAR_MM``): samples
  flagged there and trials flagged there at least once.
- The premise: median filtered force and force rate in distance bins, over all 100
  trials, with a figure of both against the labelled distance.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, atomic_write
from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig
from hapticframe_raking import RakingTrial, load_trials
from hapticframe_raking import jamming_labels as raking_jamming_labels

from ._targets import load_average, load_note

__all__ = ["FAR_MM", "JAMMING_MM", "jamming_labels", "run_raking_jamming", "trial_batch"]

JAMMING_MM = 40.0
FAR_MM = 80.0
RATE_HZ = 10.0
BIN_EDGES_MM = np.arange(0.0, 210.0, 10.0)


def trial_batch(trial: RakingTrial, t0: float = 0.0) -> SampleBatch:
    """One trial as the classifier's input: ``taxel_force`` at the nominal rate."""
    t = t0 + np.arange(len(trial)) / RATE_HZ
    return SampleBatch(t, {"taxel_force": trial.force})


def jamming_labels(trial: RakingTrial, jamming_mm: float = JAMMING_MM) -> np.ndarray:
    """0 free, 1 jamming (labelled distance at most ``jamming_mm``)."""
    return raking_jamming_labels(trial, jamming_mm)


def _classifier(config: ForceRateJammingConfig) -> ForceRateJammingClassifier:
    return ForceRateJammingClassifier(config, BuildContext("jamming", np.random.default_rng(0)))


def _binned(distance: np.ndarray, values: np.ndarray) -> list[dict[str, float]]:
    rows = []
    for lo, hi in itertools.pairwise(BIN_EDGES_MM):
        v = values[(distance >= lo) & (distance < hi) & np.isfinite(values)]
        if v.size:
            rows.append({"from_mm": float(lo), "to_mm": float(hi), "n": int(v.size),
                         "median": float(np.median(v)), "q25": float(np.quantile(v, 0.25)),
                         "q75": float(np.quantile(v, 0.75))})
    return rows


def run_raking_jamming(options: BenchOptions) -> dict[str, Any]:
    """Calibrate on the training trials, score on the test trials, check the premise."""
    training, testing = load_trials("training"), load_trials("testing")
    base = ForceRateJammingConfig(force_channel="taxel_force", sample_rate_hz=RATE_HZ,
                                  cutoff_hz=2.0, restart_after_gap_s=0.5)
    classifier = _classifier(base)
    classifier.fit([trial_batch(t) for t in training], [jamming_labels(t) for t in training])
    fitted = classifier.config
    first_flag_mm, far_flagged, far_samples, far_trials = [], 0, 0, 0
    per_trial = []
    for trial in testing:
        probs = classifier.predict_proba(trial_batch(trial))
        flagged = probs.probabilities.argmax(axis=1) != 0
        far = trial.distance_mm > FAR_MM
        far_samples += int(far.sum())
        far_flagged += int((flagged & far).sum())
        far_trials += int((flagged & far).any())
        near = flagged & ~far
        first = float(trial.distance_mm[np.flatnonzero(near)[0]]) if near.any() else None
        if first is not None:
            first_flag_mm.append(first)
        per_trial.append({"trial": trial.name, "first_flag_mm": first,
                          "flagged_while_far": int((flagged & far).sum()),
                          "end_mm": float(trial.distance_mm[-1])})
    # The premise, over all 100 trials.
    distance, force, rate = [], [], []
    curves = []
    for trial in training + testing:
        f, r = classifier.force_and_rate(trial_batch(trial))
        distance.append(trial.distance_mm)
        force.append(f)
        rate.append(r)
        curves.append((trial.distance_mm, f, r))
    d_all, f_all, r_all = (np.concatenate(x) for x in (distance, force, rate))
    flags = np.array(first_flag_mm)
    results: dict[str, Any] = {
        "force": "magnitude of the 12 normalized taxel components (authors' units, not N)",
        "rate_hz": RATE_HZ, "jamming_label_mm": JAMMING_MM, "far_mm": FAR_MM,
        "thresholds": {k: getattr(fitted, k) for k in (
            "jamming_force_n", "jamming_rate_n_per_s", "contact_force_n",
            "contact_rate_n_per_s", "cutoff_hz")},
        "test": {
            "trials": len(testing), "flagged_near": int(flags.size),
            "first_flag_mm": {"median": float(np.median(flags)) if flags.size else None,
                              "q25": float(np.quantile(flags, 0.25)) if flags.size else None,
                              "q75": float(np.quantile(flags, 0.75)) if flags.size else None,
                              "min": float(flags.min()) if flags.size else None,
                              "max": float(flags.max()) if flags.size else None},
            "far_samples": far_samples, "far_samples_flagged": far_flagged,
            "far_false_alarm_rate": far_flagged / far_samples if far_samples else None,
            "trials_flagged_while_far": far_trials, "per_trial": per_trial},
        "premise": {"force_by_distance": _binned(d_all, f_all),
                    "rate_by_distance": _binned(d_all, r_all),
                    "spearman_force_vs_distance_below_100mm": _spearman(
                        d_all, f_all, 100.0),
                    "spearman_rate_vs_distance_below_100mm": _spearman(d_all, r_all, 100.0)},
        "machine": {"load_average_1min": load_average()},
    }
    atomic_write(options.out_dir / "raking-jamming.json", json.dumps(results, indent=2) + "\n")
    atomic_write(options.out_dir / "raking-jamming.md", _markdown(results))
    drawn = _figure(options.out_dir / "raking-jamming.png", curves, results)
    t = results["test"]
    options.echo(f"thresholds: force {fitted.jamming_force_n:.3g}, rate "
                 f"{fitted.jamming_rate_n_per_s:.3g} /s (normalized units)")
    options.echo(f"test: {t['flagged_near']}/{t['trials']} trials flagged within {FAR_MM:g} mm, "
                 f"first flag at median {t['first_flag_mm']['median']} mm; far false alarms "
                 f"{far_flagged}/{far_samples} samples in {far_trials} trials")
    options.echo(f"wrote {options.out_dir / 'raking-jamming.md'}"
                 + (" and raking-jamming.png" if drawn else ""))
    options.echo(load_note(results["machine"]["load_average_1min"]))
    return {"first_flag_median_mm": t["first_flag_mm"]["median"],
            "far_false_alarm_rate": t["far_false_alarm_rate"]}


def _spearman(distance: np.ndarray, values: np.ndarray, below_mm: float) -> float | None:
    from scipy.stats import spearmanr

    keep = (distance < below_mm) & np.isfinite(values)
    if keep.sum() < 3:
        return None
    return float(spearmanr(distance[keep], values[keep]).statistic)


def _markdown(results: Mapping[str, Any]) -> str:
    t, p = results["test"], results["premise"]
    th = results["thresholds"]
    ff = t["first_flag_mm"]
    lines = [
        "# The jamming rule on real raking data", "",
        f"Force: {results['force']}; nominal {results['rate_hz']:g} Hz. Calibrated on 80 "
        f"training trials labelled jamming within {results['jamming_label_mm']:g} mm of the "
        f"object; thresholds force {th['jamming_force_n']:.4g}, force rate "
        f"{th['jamming_rate_n_per_s']:.4g} per s (low-pass {th['cutoff_hz']:g} Hz).", "",
        f"Test trials first flagged within {results['far_mm']:g} mm: {t['flagged_near']} of "
        f"{t['trials']}; distance at the first flag: median {_mm(ff['median'])}, quartiles "
        f"{_mm(ff['q25'])} to {_mm(ff['q75'])}, range {_mm(ff['min'])} to {_mm(ff['max'])}.",
        f"False alarms while far (distance > {results['far_mm']:g} mm): "
        f"{t['far_samples_flagged']} of {t['far_samples']} samples, in "
        f"{t['trials_flagged_while_far']} of {t['trials']} trials.", "",
        "| distance (mm) | median force | median force rate (/s) |", "|---|---|---|"]
    rates = {r["from_mm"]: r for r in p["rate_by_distance"]}
    for row in p["force_by_distance"]:
        rate = rates.get(row["from_mm"])
        lines.append(f"| {row['from_mm']:.0f}-{row['to_mm']:.0f} | {row['median']:.3f} | "
                     + (f"{rate['median']:.3f} |" if rate else "– |"))
    lines += ["", f"Spearman correlation with distance below 100 mm: force "
              f"{p['spearman_force_vs_distance_below_100mm']:.2f}, force rate "
              f"{p['spearman_rate_vs_distance_below_100mm']:.2f} (negative: rises as the "
              "tool nears the object).", ""]
    return "\n".join(lines)


def _mm(value: float | None) -> str:
    return "–" if value is None else f"{value:.0f} mm"


def _figure(path: Path, curves: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
            results: Mapping[str, Any]) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    th = results["thresholds"]
    for ax, index, key, threshold, label in (
            (axes[0], 1, "force_by_distance", th["jamming_force_n"], "filtered force"),
            (axes[1], 2, "rate_by_distance", th["jamming_rate_n_per_s"], "force rate (/s)")):
        for curve in curves:
            ax.plot(curve[0], curve[index], color="0.6", lw=0.4, alpha=0.5)
        rows = results["premise"][key]
        mid = [(r["from_mm"] + r["to_mm"]) / 2 for r in rows]
        ax.plot([], [], color="0.6", lw=0.6, label="each of the 100 trials")
        ax.plot(mid, [r["median"] for r in rows], "o-", color="tab:red",
                label="median per 10 mm bin")
        ax.fill_between(mid, [r["q25"] for r in rows], [r["q75"] for r in rows],
                        color="tab:red", alpha=0.2, label="interquartile range")
        ax.axhline(threshold, color="tab:blue", ls="--", label="calibrated jamming threshold")
        ax.axvspan(0, results["jamming_label_mm"], color="tab:green", alpha=0.1,
                   label="labelled jamming zone")
        ax.set_ylabel(f"{label}\n(normalized taxel units)")
        ax.legend(fontsize=7, loc="upper right")
    axes[1].set_xlabel("labelled distance to the buried object (mm)")
    axes[1].invert_xaxis()
    fig.suptitle("Real raking trials (Chen et al. 2024): force and force rate ahead of the object")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
