"""``hapticframe bench biotac-calibration --data DIR``: calibrate the synthetic BioTac on real
recordings and compare the statistics.

Reads every Penn BOLT recording in ``DIR`` (``--trials N``: N trials per object, both
fingers), measures them with ``hapticframe_biotac.calibrate_biotac`` and writes:

- ``biotac-calibration.json``: the generator's parameters
  (``hapticframe_biotac.BioTacCalibration.load`` reads it;
  ``hapticframe_biotac.generate_press_trial`` draws trials from it);
- ``biotac-calibration.md`` and ``biotac-calibration.png``: each statistic measured the
  same way (``hapticframe_biotac.calibrate_biotac``) on the real recordings, on the
  uncalibrated granular-media generator's open-air rakes past the cylinder (the same rake
  with the media removed, which starts in air as the real trials do) and on trials of the
  calibrated generator.
"""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, UsageError, atomic_write

__all__ = ["compare_statistics", "run_biotac_calibration"]

_SOURCES = ("real", "uncalibrated generator", "calibrated generator")


def _summary(cal: Any) -> dict[str, Any]:
    """The compared statistics of one calibration (one source)."""
    episodes = [e for rec in cal.episodes for e in rec]
    gain = np.asarray(cal.electrode_gain[0]) if cal.electrode_gain else np.zeros(19)
    return {
        "rest_pdc": cal.rest_pdc, "rest_pdc_spread": cal.rest_pdc_spread,
        "rest_electrodes_mean": float(np.mean(cal.rest_electrodes)),
        "rest_electrodes": list(cal.rest_electrodes), "rest_pac": cal.rest_pac,
        "noise_pdc": cal.noise_pdc, "noise_electrodes": float(np.median(cal.noise_electrodes)),
        "noise_pac": cal.noise_pac,
        "drift_pdc_per_s": cal.drift_pdc_per_s,
        "drift_electrodes_per_s": cal.drift_electrodes_per_s,
        "pac_band_rms": list(cal.pac_band_rms),
        "pac_press_gain": cal.pac_press_gain,
        "episode_peak_median": float(np.median([e["peak"] for e in episodes])),
        "episode_duration_median_s": float(np.median([e["duration_s"] for e in episodes])),
        "electrode_gain_finger0": gain.tolist(),
        "electrode_gain_abs_mean": float(np.mean(np.abs(gain))),
        "recordings": cal.recordings,
    }


def compare_statistics(real: list[Any], fingers: list[int], n_synthetic: int,
                       seed: int) -> tuple[Any, dict[str, dict[str, Any]]]:
    """The calibration of ``real`` and the statistics of the three sources."""
    from hapticframe_biotac import (
        BioTacFrames,
        TrialSpec,
        calibrate_biotac,
        generate_open_air_trial,
        generate_press_trial,
        layout_for,
    )

    calibration = calibrate_biotac(real, fingers)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 41]))
    rakes = []
    for _ in range(n_synthetic):
        trial = generate_open_air_trial(TrialSpec(
            medium="cottonwood_beads", speed_m_per_s=0.02, orientation_deg=0.0,
            object_offset_m=0.0, has_object=True), rng)
        rakes.append(BioTacFrames(layout_for("biotac"), trial.timestamps_s, trial.pac,
                                  trial.pdc, trial.tac, trial.tdc, trial.electrodes))
    presses = [generate_press_trial(calibration, rng, finger=k % 2)
               for k in range(n_synthetic)]
    stats = {
        "real": _summary(calibration),
        "uncalibrated generator": _summary(calibrate_biotac(rakes)),
        "calibrated generator": _summary(calibrate_biotac(presses)),
    }
    return calibration, stats


def save_comparison_figure(stats: dict[str, dict[str, Any]], path: Path) -> Path | None:
    """Six panels, one statistic each, the three sources side by side."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    from hapticframe_biotac import PAC_BANDS_HZ

    colours = {"real": "black", "uncalibrated generator": "tab:red",
               "calibrated generator": "tab:blue"}
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    x = np.arange(len(_SOURCES))

    def bars(ax: Any, key: str, title: str, unit: str, log: bool = False) -> None:
        values = [stats[s][key] for s in _SOURCES]
        ax.bar(x, values, color=[colours[s] for s in _SOURCES])
        ax.set_xticks(x, ["real", "uncalibrated", "calibrated"])
        ax.set_title(title)
        ax.set_ylabel(unit)
        if log:
            ax.set_yscale("log")

    bars(axes[0, 0], "rest_pdc", "resting pdc level", "counts")
    ax = axes[0, 1]
    for s in _SOURCES:
        ax.plot(np.arange(1, 20), stats[s]["rest_electrodes"], "o-", color=colours[s], label=s)
    ax.set_title("resting level per electrode")
    ax.set_xlabel("electrode")
    ax.set_ylabel("counts")
    ax.legend(fontsize=8)
    ax = axes[0, 2]
    width = 0.25
    keys = ("noise_pdc", "noise_electrodes", "noise_pac")
    for i, s in enumerate(_SOURCES):
        ax.bar(np.arange(3) + (i - 1) * width, [stats[s][k] for k in keys], width,
               color=colours[s], label=s)
    ax.set_xticks(np.arange(3), ["pdc", "electrodes (median)", "pac"])
    ax.set_title("resting noise (std)")
    ax.set_ylabel("counts")
    ax.legend(fontsize=8)
    ax = axes[1, 0]
    centres = np.sqrt(np.asarray(PAC_BANDS_HZ[:-1]) * np.asarray(PAC_BANDS_HZ[1:]))
    for s in _SOURCES:
        ax.loglog(centres, stats[s]["pac_band_rms"], "o-", color=colours[s], label=s)
    ax.set_title("pac at rest: RMS per octave band")
    ax.set_xlabel("Hz")
    ax.set_ylabel("counts")
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    for i, s in enumerate(_SOURCES):
        ax.bar(np.arange(2) + (i - 1) * width,
               [stats[s]["drift_pdc_per_s"], stats[s]["drift_electrodes_per_s"]], width,
               color=colours[s], label=s)
    ax.set_xticks(np.arange(2), ["pdc", "electrodes"])
    ax.set_title("drift between contacts (std of slopes)")
    ax.set_ylabel("counts/s")
    ax.legend(fontsize=8)
    ax = axes[1, 2]
    for s in _SOURCES:
        ax.plot(np.arange(1, 20), stats[s]["electrode_gain_finger0"], "o-", color=colours[s],
                label=f"{s} (peak pdc rise {stats[s]['episode_peak_median']:.0f})")
    ax.axhline(0.0, color="grey", lw=0.5)
    ax.set_title("press response: electrode Δ per count of pdc rise")
    ax.set_xlabel("electrode")
    ax.set_ylabel("counts / count")
    ax.legend(fontsize=8)
    fig.suptitle("BioTac statistics: real (Penn BOLT) vs the synthetic generator before and "
                 "after calibration")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _markdown(result: dict[str, Any]) -> str:
    stats = result["statistics"]
    rows = [("resting pdc (counts)", "rest_pdc", 0), ("resting electrodes, mean (counts)",
            "rest_electrodes_mean", 0), ("resting pac centre (counts)", "rest_pac", 0),
            ("noise pdc (std, counts)", "noise_pdc", 2),
            ("noise electrodes (median std, counts)", "noise_electrodes", 2),
            ("noise pac (std, counts)", "noise_pac", 2),
            ("drift pdc (std of slopes, counts/s)", "drift_pdc_per_s", 3),
            ("drift electrodes (counts/s)", "drift_electrodes_per_s", 3),
            ("pac vibration per count of |Δpdc|", "pac_press_gain", 2),
            ("contact episode peak pdc rise (median, counts)", "episode_peak_median", 0),
            ("contact episode duration (median, s)", "episode_duration_median_s", 2),
            ("electrode response, mean |gain| (counts per count)", "electrode_gain_abs_mean", 3)]
    lines = ["# BioTac calibration: real against synthetic", "",
             f"Command `{result['command']}`; {result['recordings']} real recordings; "
             f"{result['synthetic_trials']} synthetic trials per generator; "
             f"{result['timing_s']:.1f} s; load {result['load_average_1min']:.1f}.", "",
             "| statistic | real | uncalibrated | calibrated |", "|---|---|---|---|"]
    for label, key, digits in rows:
        lines.append(f"| {label} | " + " | ".join(
            f"{stats[s][key]:.{digits}f}" for s in _SOURCES) + " |")
    return "\n".join(lines) + "\n"


def run_biotac_calibration(options: BenchOptions) -> dict[str, Any]:
    """Write biotac-calibration.json (the parameters), .md and .png."""
    from hapticframe_biotac import ReplayFormatError, load_bolt_dir

    if options.data is None:
        raise UsageError("biotac-calibration needs --data DIR (a directory of Penn BOLT .h5 "
                         "files)")
    started = time.perf_counter()
    try:
        trials = load_bolt_dir(options.data)
    except ReplayFormatError as exc:
        raise UsageError(f"--data: {exc}") from exc
    if options.trials is not None:
        keep: dict[str, list[str]] = {}
        for t in trials:
            names = keep.setdefault(t.object, [])
            if t.trial not in names and len(names) < options.trials:
                names.append(t.trial)
        trials = [t for t in trials if t.trial in keep[t.object]]
    n_synthetic = 10 if options.quick else 40
    options.echo(f"biotac-calibration: {len(trials)} recordings, {n_synthetic} synthetic "
                 "trials per generator")
    try:
        calibration, stats = compare_statistics([t.frames for t in trials],
                                                [t.finger for t in trials], n_synthetic,
                                                options.seed)
    except ValueError as exc:
        raise UsageError(f"--data {options.data}: {exc}") from exc
    out = Path(options.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    calibration.save(out / "biotac-calibration.json")
    result = {"statistics": stats, "recordings": len(trials),
              "synthetic_trials": n_synthetic, "timing_s": time.perf_counter() - started,
              "load_average_1min": os.getloadavg()[0], "platform": platform.platform(),
              "command": "hapticframe bench biotac-calibration --data DIR"
                         + (" --quick" if options.quick else "")
                         + (f" --trials {options.trials}" if options.trials else "")}
    atomic_write(out / "biotac-calibration-statistics.json",
                 json.dumps(result, indent=1, allow_nan=False) + "\n")
    atomic_write(out / "biotac-calibration.md", _markdown(result))
    save_comparison_figure(stats, out / "biotac-calibration.png")
    options.echo(f"wrote {out / 'biotac-calibration.json'} (the generator's parameters), "
                 f"biotac-calibration.md and .png in {result['timing_s']:.1f} s")
    return result
