"""``hapticframe bench raking-real``: ours against the authors' models on the 20 real test trials.

The data and models of Chen, Versace & Jamone (IROS 2024) ship with ``hapticframe_raking``.
For each of the paper's input sets (1 or 4 taxels, normal force only or 3-axis), the
authors' three trained Keras LSTMs (read with h5py, run in numpy) and our multi-head
``raking-estimator`` (trained here on the 80 training trials, ``--trials`` seeds, default 3;
``--quick``: 1) are scored on the same test steps: every step from the 5th to the last of
each trial (the authors' ``test_main.py``: each 5-step window's last step), direction and
depth accuracy and the distance's mean absolute error in mm, per trial; and the estimate
at each trial's last step (the tool at the object). The verdict per task and input set is
on the all-steps protocol: ours at least as good as theirs (accuracy not lower, MAE not
higher), averaged over the training seeds. Per-step cost is the streaming ``update`` of one
sample on one thread, median over a test trial.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import platform
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, atomic_write
from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_raking import (
    INPUT_SETS,
    AuthorsModels,
    RakingEstimator,
    RakingEstimatorConfig,
    TrainingTrial,
    authors_models_dir,
    fit_model,
    keras_check,
    load_trials,
    score_trials,
    select_inputs,
    selected_settings,
    summarize,
)

from ._targets import load_average, load_note

__all__ = ["TASKS", "run_raking_real", "render_raking_markdown"]

#: (task, score key, higher is better, unit).
TASKS = (
    ("direction", "direction_accuracy", True, ""),
    ("depth", "depth_accuracy", True, ""),
    ("distance", "distance_mae_mm", False, "mm"),
)
_FINAL = {"direction": "final_direction_correct", "depth": "final_depth_correct",
          "distance": "final_distance_error_mm"}
STEP_TARGET_MS = 1.0


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[str]:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        yield "not limited (threadpoolctl is not installed)"
        return
    with threadpool_limits(limits=1):
        yield "1 (threadpoolctl)"


def _per_step_ms(model_dir: Path, input_set: str, trial_force: np.ndarray,
                 window_steps: int = 10) -> float:
    """Median wall time of one streaming update of one sample (ms)."""
    estimator = RakingEstimator(
        RakingEstimatorConfig(input_set=input_set, window_steps=window_steps,  # type: ignore[arg-type]
                              model_dir=str(model_dir)),
        BuildContext("timing", np.random.default_rng(0)))
    times = []
    for i in range(len(trial_force)):
        batch = SampleBatch(np.array([0.1 * i]), {"taxel_force": trial_force[i:i + 1]})
        start = time.perf_counter()
        estimator.update(batch)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def _authors_step_ms(models: AuthorsModels, inputs: np.ndarray) -> float:
    """Median wall time of the authors' three models on one 5-step window (ms)."""
    times = []
    for i in range(5, len(inputs) + 1):
        window = inputs[None, i - 5:i]
        start = time.perf_counter()
        models.direction(window)
        models.depth(window)
        models.distance(window)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


#: Per-trial scores closer than this count as a tie in the paired comparison.
_TIE = 1e-9
PROTOCOLS = (("all_steps", "every step from the 5th"), ("last_step", "each trial's last step"))


#: Bins of the distance error's profile: by true distance (mm) and by step (1-based).
DISTANCE_BINS_MM = (0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0)
STEP_BINS = (5, 15, 25, 35, 45, 55, 65, 80)


def _error_profile(estimates: Sequence[np.ndarray], testing: Sequence[Any]
                   ) -> dict[str, list[float | None]]:
    """Mean absolute distance error (mm) per true-distance bin and per step bin, from the
    5th step, over all test trials; ``estimates[i]`` are trial i's per-step estimates from
    its 5th step on."""
    err = np.concatenate([np.abs(e - t.distance_mm[4:]) for e, t in
                          zip(estimates, testing, strict=True)])
    dist = np.concatenate([t.distance_mm[4:] for t in testing])
    step = np.concatenate([np.arange(5, len(t) + 1) for t in testing])

    def binned(values: np.ndarray, edges: Sequence[float]) -> list[float | None]:
        out: list[float | None] = []
        for lo, hi in itertools.pairwise(edges):
            m = (values >= lo) & (values < hi)
            out.append(float(err[m].mean()) if m.any() else None)
        return out

    return {"by_distance": binned(dist, DISTANCE_BINS_MM), "by_step": binned(step, STEP_BINS)}


def _compare(ours: np.ndarray, theirs: np.ndarray, higher_better: bool) -> dict[str, Any]:
    """Mean and median of each, the paired wins, ties and losses of ours, a signed-rank test.

    Met: ours at least as good as theirs in both the mean and the median over trials.
    """
    from scipy.stats import wilcoxon

    gain = (ours - theirs) if higher_better else (theirs - ours)  # > 0: ours better
    nonzero = np.abs(gain) > _TIE
    p = float(wilcoxon(ours[nonzero], theirs[nonzero]).pvalue) if nonzero.sum() >= 1 else 1.0

    def at_least(a: float, b: float) -> bool:
        return bool(a >= b - _TIE) if higher_better else bool(a <= b + _TIE)

    mean_ok = at_least(float(ours.mean()), float(theirs.mean()))
    median_ok = at_least(float(np.median(ours)), float(np.median(theirs)))
    return {"ours_mean": float(ours.mean()), "theirs_mean": float(theirs.mean()),
            "ours_median": float(np.median(ours)), "theirs_median": float(np.median(theirs)),
            "wins": int((gain > _TIE).sum()), "ties": int((~nonzero).sum()),
            "losses": int((gain < -_TIE).sum()), "wilcoxon_p": p,
            "mean_met": mean_ok, "median_met": median_ok,
            "verdict": "met" if mean_ok and median_ok else "missed"}


def _verdicts(per_trial: Mapping[str, np.ndarray], theirs: Any) -> dict[str, Any]:
    """Per task: both protocols compared, and met where both are."""
    out: dict[str, Any] = {}
    for task, key, higher, _ in TASKS:
        protocols = {name: _compare(np.asarray(per_trial[k]), np.asarray(getattr(theirs, k)),
                                    higher)
                     for (name, _), k in zip(PROTOCOLS, (key, _FINAL[task]), strict=True)}
        met = all(v["verdict"] == "met" for v in protocols.values())
        out[task] = protocols | {"verdict": "met" if met else "missed"}
    return out


def run_raking_real(options: BenchOptions) -> dict[str, Any]:
    """Score ours and the authors' models; write ``raking-real.json`` and ``raking-real.md``."""
    seeds = 1 if options.quick else (options.trials or 3)
    training, testing = load_trials("training"), load_trials("testing")
    results: dict[str, Any] = {
        "data": {"training_trials": len(training), "testing_trials": len(testing),
                 "testing_steps_scored": int(sum(len(t) - 4 for t in testing))},
        "seeds": seeds, "settings": {}, "input_sets": {}}
    options.echo(f"raking-real: {len(training)} training and {len(testing)} test trials, "
                 f"{seeds} training seed(s) per input set")
    with _one_blas_thread() as blas, tempfile.TemporaryDirectory() as scratch:
        results["blas_threads"] = blas
        for input_set in INPUT_SETS:
            settings = selected_settings(input_set)
            results["settings"][input_set] = settings.__dict__
            authors = AuthorsModels.load(input_set)
            theirs = score_trials(authors.estimate_trial, testing, input_set)
            trials = [TrainingTrial(select_inputs(t.force, input_set), t.distance_mm,
                                    t.direction, t.depth) for t in training]
            ours_runs, train_s = [], []
            model_dir = Path(scratch) / input_set
            model_dir.mkdir()
            for seed in range(seeds):
                model, report = fit_model(trials, settings,
                                          np.random.default_rng(options.seed + seed))
                train_s.append(report["train_s"])
                ours_runs.append(score_trials(model.estimate_trial, testing, input_set))
                if seed == 0:
                    model.save(model_dir)
                    ours_steps = [model.estimate_trial(select_inputs(t.force, input_set))
                                  .distance_mm[4:] for t in testing]
            per_trial = {key: np.mean([getattr(r, key) for r in ours_runs], axis=0)
                         for key in summarize(theirs)}
            ours_summary = {key: {"mean": float(v.mean()), "std": float(v.std()),
                                  "median": float(np.median(v)), "min": float(v.min()),
                                  "max": float(v.max())} for key, v in per_trial.items()}
            seed_means = {key: [float(getattr(r, key).mean()) for r in ours_runs]
                          for key in per_trial}
            entry: dict[str, Any] = {
                "ours": ours_summary, "ours_seed_means": seed_means,
                "theirs": summarize(theirs), "train_s_median": float(np.median(train_s)),
                "per_trial": {"names": list(theirs.names),
                              "ours": {k: v.tolist() for k, v in per_trial.items()},
                              "theirs": {k: getattr(theirs, k).tolist() for k in per_trial}},
                "comparison": _verdicts(per_trial, theirs),
                "error_profile": {
                    "ours_seed0": _error_profile(ours_steps, testing),
                    "theirs": _error_profile([authors.estimate_trial(select_inputs(
                        t.force, input_set)).distance_mm for t in testing], testing)}}
            entry["verdicts"] = {task: entry["comparison"][task]["verdict"]
                                 for task, *_ in TASKS}
            force = testing[0].force
            entry["ours_step_ms"] = _per_step_ms(model_dir, input_set, force,
                                                 settings.window_steps)
            entry["theirs_step_ms"] = _authors_step_ms(authors,
                                                       select_inputs(force, input_set))
            entry["verdicts"]["step_time"] = ("met" if entry["ours_step_ms"] <= STEP_TARGET_MS
                                              else "missed")
            results["input_sets"][input_set] = entry
            options.echo(_line(input_set, entry))
        results["keras_check"] = _keras(testing, options)
    results["machine"] = {"platform": platform.platform(), "numpy": np.__version__,
                          "load_average_1min": load_average()}
    task_verdicts = [e["verdicts"][task] for e in results["input_sets"].values()
                     for task, *_ in TASKS]
    results["verdicts_met"] = f"{task_verdicts.count('met')} of {len(task_verdicts)}"
    keras = results["keras_check"]
    results["all_met"] = all(v == "met" for e in results["input_sets"].values()
                             for v in e["verdicts"].values()) and (
        keras.get("within_tolerance", True))
    options.echo(f"  verdicts met (both protocols, mean and median): {results['verdicts_met']}")
    atomic_write(options.out_dir / "raking-real.json", json.dumps(results, indent=2) + "\n")
    atomic_write(options.out_dir / "raking-real.md", render_raking_markdown(results))
    _figure(options.out_dir / "raking-real.png", results)
    options.echo(load_note(results["machine"]["load_average_1min"]))
    options.echo(f"wrote {options.out_dir / 'raking-real.md'} and raking-real.json")
    return {"all_met": results["all_met"], "verdicts_met": results["verdicts_met"],
            "keras_within_tolerance": keras.get("within_tolerance", keras.get("skipped")),
            **{f"{s}_{task}": e["verdicts"][task] for s, e in results["input_sets"].items()
               for task, *_ in TASKS}}


def _keras(testing: Any, options: BenchOptions) -> dict[str, Any]:
    """The port against Keras itself on the test windows (skipped without Keras 3)."""
    report = keras_check(testing, authors_models_dir())
    if "skipped" in report:
        options.echo(f"  keras check skipped: {report['skipped']}")
    else:
        options.echo(f"  keras check ({report['keras']}, {report['backend']}): port within "
                     f"{report['max_relative_difference']:.1e} of Keras in float64 on "
                     f"{report['windows']} windows x {len(report['models'])} models "
                     f"(tolerance {report['tolerance']:.0e}); as the authors ran it, float32: "
                     f"{report['float32_max_relative_difference']:.1e}")
    return report


def _line(input_set: str, entry: Mapping[str, Any]) -> str:
    parts = []
    for task, _, _, unit in TASKS:
        c = entry["comparison"][task]
        a, b = c["all_steps"], c["last_step"]
        parts.append(f"{task} {a['ours_mean']:.3g}{unit} vs {a['theirs_mean']:.3g}{unit} "
                     f"(last {b['ours_mean']:.3g} vs {b['theirs_mean']:.3g}) "
                     f"{entry['verdicts'][task]}")
    return (f"  {input_set:9s} " + "; ".join(parts)
            + f"; step {entry['ours_step_ms']:.3f} ms {entry['verdicts']['step_time']}")


def _cell(stats: Mapping[str, float], unit: str) -> str:
    if unit:
        return f"{stats['mean']:.1f} ± {stats['std']:.1f} (median {stats['median']:.1f})"
    return f"{stats['mean']:.3f} ± {stats['std']:.3f} (median {stats['median']:.3f})"


def _number(value: float, unit: str) -> str:
    return f"{value:.1f}" if unit else f"{value:.3f}"


def _keras_lines(keras: Mapping[str, Any]) -> list[str]:
    lines = ["## The port against Keras itself", ""]
    if "skipped" in keras:
        return [*lines, f"Skipped: {keras['skipped']}."]
    lines += [
        f"Keras {keras['keras']} ({keras['backend']} backend). `keras.models.load_model` on "
        f"the authors' files: {'; '.join(keras['keras3_load_model'])} (their Keras 2 LSTM "
        "config carries `time_major`, which Keras 3 no longer takes). So each model is built "
        "as their `train_main.py` builds it and Keras's own HDF5 reader sets its weights "
        f"(`load_weights`). On all {keras['windows']} test windows: largest difference of the "
        f"port from Keras, relative to max(1, |output|), **{keras['max_relative_difference']:.1e}"
        f"** in float64 (whole model and layer by layer; tolerance "
        f"{keras['tolerance']:.0e}: {'met' if keras['within_tolerance'] else 'missed'}); "
        f"against Keras in float32, as the authors ran it: "
        f"{keras['float32_max_relative_difference']:.1e} (float32 rounding). Keras 3 "
        "multiplies a Dense layer's inputs in float32 even in a float64 model (its type "
        "promotion makes 64-bit results 32-bit), so the Dense rows agree to float32 rounding "
        "and the LSTM rows to float64 rounding.",
        "",
        "| input set | task | float64, per layer | float64, whole | float32, whole |",
        "|---|---|---|---|---|"]
    for m in keras["models"]:
        layers = ", ".join(f"{x['layer']}({x['units']}) {x['max_relative_difference']:.0e}"
                           for x in m["layers_float64"])
        lines.append(f"| {m['input_set']} | {m['task']} | {layers} | "
                     f"{m['whole_float64_max_abs_difference']:.1e} abs | "
                     f"{m['whole_float32_max_relative_difference']:.1e} |")
    return lines


def render_raking_markdown(results: Mapping[str, Any]) -> str:
    """The report: the verdicts with their paired comparison, a table per protocol, ours
    beside theirs, the cost and the Keras check."""
    machine = results["machine"]
    lines = [
        "# Real raking data: ours against the authors' models",
        "",
        f"{results['data']['testing_trials']} test trials "
        f"({results['data']['testing_steps_scored']} scored steps), our estimator trained "
        f"on {results['data']['training_trials']} trials with {results['seeds']} seed(s); "
        f"over test trials (ours: each trial's score averaged over the seeds). Our settings "
        f"per input set were chosen by cross-validation on the training trials only "
        f"(`hapticframe bench raking-real-cv`). {machine['platform']}; BLAS threads "
        f"{results['blas_threads']}; {load_note(machine['load_average_1min'])}.",
        "",
        f"## Verdicts: {results['verdicts_met']} met",
        "",
        "Met: ours at least as good as theirs in both the mean and the median over the test "
        "trials, on both protocols (every step from the 5th; each trial's last step). Paired "
        "per trial: wins / ties / losses of ours, and the Wilcoxon signed-rank p (two-sided, "
        "ties left out).",
        "",
        "| input set | task | protocol | ours mean | theirs mean | ours median | theirs median "
        "| wins / ties / losses | p | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for input_set, e in results["input_sets"].items():
        for task, _, _, unit in TASKS:
            c = e["comparison"][task]
            for protocol, label in PROTOCOLS:
                v = c[protocol]
                lines.append(
                    f"| {input_set} | {task}{' (mm)' if unit else ''} | {label} | "
                    f"{_number(v['ours_mean'], unit)} | {_number(v['theirs_mean'], unit)} | "
                    f"{_number(v['ours_median'], unit)} | "
                    f"{_number(v['theirs_median'], unit)} | "
                    f"{v['wins']} / {v['ties']} / {v['losses']} | {v['wilcoxon_p']:.2g} | "
                    f"{v['verdict']} |")
    lines += [
        "",
        "## Every step from the 5th (the authors' test_main.py protocol)",
        "",
        "| input set | task | ours | theirs | verdict |",
        "|---|---|---|---|---|",
    ]
    for input_set, e in results["input_sets"].items():
        for task, key, _, unit in TASKS:
            name = f"{task} {'MAE (mm)' if unit else 'accuracy'}"
            lines.append(f"| {input_set} | {name} | {_cell(e['ours'][key], unit)} | "
                         f"{_cell(e['theirs'][key], unit)} | "
                         f"{e['comparison'][task]['all_steps']['verdict']} |")
    lines += ["", "## Where the distance error is", "",
              "Mean absolute distance error (mm) over the test steps, ours (seed 0) | theirs, "
              "by true distance and by step.", "",
              "| bin | " + " | ".join(results["input_sets"]) + " |",
              "|---|" + "---|" * len(results["input_sets"])]
    for kind, edges, unit in (("by_distance", DISTANCE_BINS_MM, "mm"),
                              ("by_step", STEP_BINS, "")):
        for i, (lo, hi) in enumerate(itertools.pairwise(edges)):
            label = (f"{lo:.0f}–{hi:.0f} mm" if unit else f"steps {lo}–{hi - 1}")
            cells = []
            for e in results["input_sets"].values():
                o = e["error_profile"]["ours_seed0"][kind][i]
                t = e["error_profile"]["theirs"][kind][i]
                cells.append("–" if o is None or t is None else f"{o:.1f} \\| {t:.1f}")
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += ["", "## At each trial's last step (the tool at the object)", "",
              "| input set | direction correct | depth correct | distance error (mm) |",
              "|---|---|---|---|"]
    for input_set, e in results["input_sets"].items():
        cells = []
        for task, _, _, unit in TASKS:
            key = _FINAL[task]
            o, t = e["ours"][key], e["theirs"][key]
            cells.append(f"{o['mean']:.2f} vs {t['mean']:.2f}" if not unit else
                         f"{o['mean']:.1f} vs {t['mean']:.1f}")
        lines.append(f"| {input_set} | " + " | ".join(cells) + " |")
    lines += ["", "(ours vs theirs)", "", "## Cost", "",
              "| input set | ours per step (ms) | theirs per step, 3 models (ms) | "
              "training (s, median) | verdict (≤ 1 ms) |", "|---|---|---|---|---|"]
    for input_set, e in results["input_sets"].items():
        lines.append(f"| {input_set} | {e['ours_step_ms']:.3f} | {e['theirs_step_ms']:.3f} "
                     f"| {e['train_s_median']:.1f} | {e['verdicts']['step_time']} |")
    lines += ["", "## Our settings and means per training seed", ""]
    for input_set, e in results["input_sets"].items():
        s = results["settings"][input_set]
        cells = [f"{task} " + ", ".join(f"{v:.3g}" for v in e["ours_seed_means"][key])
                 for task, key, _, _ in TASKS]
        lines.append(f"- {input_set} (window {s['window_steps']}, first "
                     f"{s['skip_first_steps']} steps left out, distance capped at "
                     f"{s['range_mm']} mm): " + "; ".join(cells))
    lines += ["", *_keras_lines(results["keras_check"])]
    return "\n".join(lines) + "\n"


def _figure(path: Path, results: Mapping[str, Any]) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    sets = list(results["input_sets"])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, (task, key, _, unit) in zip(axes, TASKS, strict=True):
        for offset, who, color in ((-0.18, "ours", "tab:blue"), (0.18, "theirs", "tab:orange")):
            values = [results["input_sets"][s]["per_trial"][who][key] for s in sets]
            x = np.arange(len(sets)) + offset
            ax.boxplot(values, positions=x, widths=0.3, patch_artist=True,
                       boxprops={"facecolor": color, "alpha": 0.5}, medianprops={"color": "k"})
            ax.plot([], [], "s", color=color, alpha=0.5,
                    label="ours (raking-estimator)" if who == "ours" else "theirs (Keras LSTMs)")
        ax.set_xticks(np.arange(len(sets)), sets, fontsize=8)
        ax.set_title(f"{task} {'MAE (mm)' if unit else 'accuracy'} per test trial")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
