"""``hapticframe bench jamming-detection``: jamming detection in units of the sand at hand.

Issue 32 section 1. Two classifiers, each with its defaults and fitted by its own ``fit``
(what ``hapticframe train`` calls) on training movements of the world it is scored in:

- ``force-rate-jamming``: absolute force and force-rate thresholds (thesis Figure 3.4);
  fitted with ``calibration_force_floor: free-drag``, as ``calibrate-physics.yaml`` does;
- ``drag-ratio-jamming``: force relative to the movement's own free drag (a CUSUM on the
  log-ratio), fitted to at most 1 false alarm per metre of free raking; and, for the
  transfer the ratio is for, fitted in the *other* world.

Worlds and data:

- ``sandbox`` and ``mpm-sand``: movements of a plate at 5 cm/s, 0.3 N of noise per axis
  (the ``sandbox-force`` sensor's default) at four depths (4.4, 3.4, 2.9, 2.0 cm); the
  approaches aim at an object 0, 2 or 4 cm to the side of the plate's path; free rakes of
  60 cm pass no object. Training: a 3 cm circle; testing: other seeds, a 9 x 5 cm ellipse
  at 35 degrees and a 2.5 cm circle, so the test is not the training set.
- ``raking-real``: the real raking trials of Chen et al. (``hapticframe_raking``, taxel
  force in the authors' normalized units, 10 Hz): fitted on the 80 training trials
  (jamming within 40 mm), scored on the 20 test trials; free raking is the stretch farther
  than 80 mm from the object.

Measures, on the test movements only:

- per-sample ROC AUC of each classifier's interaction score (the log-odds of not free),
  positives the samples labelled jamming or contact, negatives the free ones;
- at 1 false alarm per metre of free raking: the score threshold with the most detections
  whose alarm onsets on free-labelled samples stay within 1 per metre of free raking
  (the oracle operating point of that score), and the distance to the object (the
  plate's centre to the nearest point of the outline) when each approach is first
  flagged; the same at the classifier's own operating point (its arg-max), with its
  measured false alarms per metre.

Outputs: ``jamming-detection.json``, ``jamming-detection.md`` and, with matplotlib,
``jamming-detection.png`` (the ROC curves).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import BenchOptions, Circle, Ellipse, Scene, atomic_write
from hapticframe.kinds import BuildContext, ExploratoryMovement, SampleBatch
from hapticframe_jamming import (
    DragRatioJammingClassifier,
    DragRatioJammingConfig,
    ForceRateJammingClassifier,
    ForceRateJammingConfig,
)
from hapticframe_raking import load_trials

from ._raking_jamming import FAR_MM, RATE_HZ, jamming_labels, trial_batch
from ._targets import load_average, load_note

__all__ = ["Movement", "run_jamming_detection", "world_movements"]

SPEED_M_PER_S = 0.05
NOISE_STD_N = 0.3
DEPTHS_M = (0.044, 0.034, 0.029, 0.02)
OFFSETS_M = (0.0, 0.02, 0.04)
FREE_LENGTH_M = 0.6
WORLDS = ("sandbox", "mpm-sand")
#: The false-alarm budget of the operating point (per metre of free raking).
BUDGET_PER_M = 1.0

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Movement:
    """One recorded movement: the measured force, the truth and where the object is."""

    batch: SampleBatch
    labels: NDArray[np.int64]
    distance_m: FloatArray  # plate centre to the object's outline, per sample (inf: none)
    step_m: FloatArray  # distance travelled per sample
    approach: bool


def _robot(world: str, depth: float, scene: Scene, seed: int) -> Any:
    context = BuildContext(id="arm", rng=np.random.default_rng(seed), scene=scene)
    if world == "sandbox":
        from hapticframe_sandbox import SandboxRobot, SandboxRobotConfig

        return SandboxRobot(SandboxRobotConfig(depth_m=depth), context)
    from hapticframe_mpm_sand import MpmSandRobot, MpmSandRobotConfig

    return MpmSandRobot(MpmSandRobotConfig(depth_m=depth), context)


def _rake(world: str, depth: float, obj: Any | None, start: tuple[float, float],
          end: tuple[float, float], seed: int) -> Movement:
    # A far-away object keeps the scene valid for a free rake; the plate never nears it.
    scene_obj = obj if obj is not None else Circle(center_m=(0.72, 0.47), radius_m=0.02)
    robot = _robot(world, depth, Scene(objects=[scene_obj]), seed)
    robot.begin(ExploratoryMovement(np.array(start), np.array(end), speed_m_per_s=SPEED_M_PER_S,
                                    depth_m=depth))
    while robot.step() is not None:
        pass
    truth = robot.ground_truth
    noise = NOISE_STD_N * np.random.default_rng(seed + 7919).standard_normal(truth.forces_n.shape)
    batch = SampleBatch(truth.timestamps_s, {"force_n": truth.forces_n + noise})
    pos = truth.positions_m
    if obj is None:
        distance = np.full(len(pos), np.inf)
    else:
        outline = np.asarray(obj.outline(512), dtype=np.float64)
        distance = np.min(np.linalg.norm(pos[:, None, :] - outline[None], axis=2), axis=1)
    step = np.concatenate([[0.0], np.linalg.norm(np.diff(pos, axis=0), axis=1)])
    return Movement(batch, truth.states.astype(np.int64), distance, step, obj is not None)


def world_movements(world: str, split: str, seed: int, depths: Sequence[float] = DEPTHS_M
                    ) -> list[Movement]:
    """The training or testing movements of one world (see the module docstring)."""
    base = seed + (0 if split == "train" else 5000)
    y0 = 0.25
    out = []
    k = 0
    for depth in depths:
        for offset in OFFSETS_M:
            if split == "train":
                obj: Any = Circle(center_m=(0.40, y0 + offset), radius_m=0.03)
            elif offset == OFFSETS_M[1]:
                obj = Circle(center_m=(0.40, y0 + offset), radius_m=0.025)
            else:
                obj = Ellipse(center_m=(0.40, y0 + offset), semi_axes_m=(0.045, 0.025),
                              orientation_deg=35.0)
            out.append(_rake(world, depth, obj, (0.05, y0), (0.45, y0), base + k))
            k += 1
        out.append(_rake(world, depth, None, (0.05, y0), (0.05 + FREE_LENGTH_M, y0), base + k))
        k += 1
    return out


# --- scores ---------------------------------------------------------------------------------


def _logsumexp2(a: FloatArray, b: FloatArray) -> FloatArray:
    top = np.maximum(a, b)
    return top + np.log(np.exp(a - top) + np.exp(b - top))


def _interaction_logits(m_j: FloatArray, m_c: FloatArray) -> FloatArray:
    """Log-odds of not free from the two margins, as both classifiers' softmax makes it."""
    jam = np.clip(m_j, -1e6, 1e6)
    contact = np.clip(m_c + np.maximum(m_j, 0.0), -1e6, 1e6)
    return _logsumexp2(jam, contact)


def force_rate_scores(clf: ForceRateJammingClassifier, batch: SampleBatch) -> FloatArray:
    """Per sample: the log-odds of not free of ``force-rate-jamming``."""
    from hapticframe_jamming import and_rule_margin

    cfg = clf.config
    force, rate = clf.force_and_rate(batch)
    m_j = and_rule_margin(force, rate, cfg.jamming_force_n, cfg.jamming_rate_n_per_s,
                          cfg.force_scale_n, cfg.rate_scale_n_per_s)
    m_c = and_rule_margin(force, rate, cfg.contact_force_n, cfg.contact_rate_n_per_s,
                          cfg.force_scale_n, cfg.rate_scale_n_per_s)
    return np.nan_to_num(_interaction_logits(m_j, m_c), nan=-1e6)


def drag_ratio_scores(clf: DragRatioJammingClassifier, batch: SampleBatch) -> FloatArray:
    """Per sample: the log-odds of not free of ``drag-ratio-jamming`` (CUSUM 0 unarmed)."""
    cfg = clf.config
    tr = clf.trace(batch)
    cusum = np.where(tr.armed, tr.cusum, 0.0)
    m_j = (cusum - cfg.cusum_threshold) / cfg.cusum_scale
    m_c = np.minimum((tr.ratio - cfg.contact_ratio) / cfg.ratio_scale,
                     (tr.ratio_rate_per_s - cfg.contact_ratio_rate_per_s)
                     / cfg.ratio_rate_scale_per_s)
    scores = _interaction_logits(m_j, m_c)
    return np.where(np.isfinite(tr.force), scores, -1e6)


def roc_auc(scores: FloatArray, positive: NDArray[np.bool_]) -> float | None:
    """Area under the ROC curve (ties count half); None without both classes."""
    from scipy.stats import rankdata

    pos, neg = int(positive.sum()), int((~positive).sum())
    if pos == 0 or neg == 0:
        return None
    ranks = rankdata(scores)
    return float((ranks[positive].sum() - pos * (pos + 1) / 2) / (pos * neg))


def roc_curve(scores: FloatArray, positive: NDArray[np.bool_], points: int = 200
              ) -> tuple[list[float], list[float]]:
    """False- and true-positive rates at ``points`` thresholds over the scores' quantiles."""
    thresholds = np.unique(np.quantile(scores, np.linspace(0, 1, points)))
    fpr = [float(np.mean(scores[~positive] > t)) for t in thresholds[::-1]]
    tpr = [float(np.mean(scores[positive] > t)) for t in thresholds[::-1]]
    return [0.0, *fpr, 1.0], [0.0, *tpr, 1.0]


@dataclass(frozen=True)
class Scored:
    """A classifier's scores on a set of movements, with what they are scored against."""

    scores: list[FloatArray]
    flagged: list[NDArray[np.bool_]]  # the classifier's own arg-max != free
    movements: Sequence[Movement]


def _onsets(flag: NDArray[np.bool_], counted: NDArray[np.bool_]) -> int:
    rising = flag & ~np.concatenate([[False], flag[:-1]])
    return int(np.sum(rising & counted))


def _free(m: Movement) -> NDArray[np.bool_]:
    return np.asarray(m.labels == 0)


def detection(flags: Sequence[NDArray[np.bool_]], movements: Sequence[Movement]
              ) -> dict[str, Any]:
    """False alarms per metre of free raking and the distance at each approach's first flag."""
    free_m = sum(float(m.step_m[_free(m)].sum()) for m in movements)
    alarms = sum(_onsets(f, _free(m)) for f, m in zip(flags, movements, strict=True))
    distances: list[float | None] = []
    early = late = missed = 0
    for f, m in zip(flags, movements, strict=True):
        if not m.approach:
            continue
        hits = np.flatnonzero(f)
        if not hits.size:
            missed += 1
            distances.append(None)
            continue
        truth = int(m.labels[hits[0]])
        early += truth == 1
        late += truth == 2
        distances.append(float(m.distance_m[hits[0]]))
    got = np.array([d for d in distances if d is not None])
    return {
        "false_alarms": alarms, "free_distance_m": free_m,
        "false_alarms_per_m": alarms / free_m if free_m else None,
        "approaches": len(distances), "early": early, "late": late, "missed": missed,
        "first_flag_in_free": len(distances) - early - late - missed,
        "distance_at_first_flag_cm": {
            "median": float(100 * np.median(got)) if got.size else None,
            "q25": float(100 * np.quantile(got, 0.25)) if got.size else None,
            "q75": float(100 * np.quantile(got, 0.75)) if got.size else None},
        "per_approach_cm": [None if d is None else round(100 * d, 2) for d in distances],
    }


def at_budget(scored: Scored, budget_per_m: float = BUDGET_PER_M) -> dict[str, Any]:
    """The lowest score threshold whose false alarms stay within the budget, and its
    detections (the oracle operating point of the score on these movements)."""
    pooled = np.concatenate(scored.scores)
    candidates = np.unique(np.quantile(pooled, np.linspace(0.0, 1.0, 400)))
    free_m = sum(float(m.step_m[_free(m)].sum()) for m in scored.movements)
    best: tuple[float, dict[str, Any]] | None = None
    for threshold in candidates[::-1]:  # strictest first; stop at the first over budget
        flags = [s > threshold for s in scored.scores]
        result = detection(flags, scored.movements)
        if result["false_alarms"] > budget_per_m * free_m:
            break
        best = (float(threshold), result)
    if best is None:
        return {"threshold": None, "budget_per_m": budget_per_m}
    return {"threshold": best[0], "budget_per_m": budget_per_m, **best[1]}


def evaluate(scored: Scored, positive: Callable[[Movement], NDArray[np.bool_]],
             negative: Callable[[Movement], NDArray[np.bool_]]) -> dict[str, Any]:
    """Per-sample ROC AUC, the budgeted operating point and the classifier's own."""
    pos = np.concatenate([positive(m) for m in scored.movements])
    neg = np.concatenate([negative(m) for m in scored.movements])
    keep = pos | neg
    scores = np.concatenate(scored.scores)[keep]
    auc = roc_auc(scores, pos[keep])
    fpr, tpr = roc_curve(scores, pos[keep])
    return {"roc_auc": auc, "roc": {"fpr": fpr, "tpr": tpr},
            "at_budget": at_budget(scored), "own": detection(scored.flagged, scored.movements)}


def _score(clf: Any, movements: Sequence[Movement]) -> Scored:
    fn = force_rate_scores if isinstance(clf, ForceRateJammingClassifier) else drag_ratio_scores
    scores = [fn(clf, m.batch) for m in movements]
    flagged = [clf.predict(m.batch) != 0 for m in movements]
    return Scored(scores, flagged, movements)


def _build(kind: str, config: Any) -> Any:
    context = BuildContext(id="jamming", rng=np.random.default_rng(0))
    if kind == "force-rate-jamming":
        return ForceRateJammingClassifier(config, context)
    return DragRatioJammingClassifier(config, context)


def _fitted(kind: str, config: Any, movements: Sequence[Movement]) -> Any:
    clf = _build(kind, config)
    clf.fit([m.batch for m in movements], [m.labels for m in movements])
    return clf


def _thresholds(clf: Any) -> dict[str, float]:
    keys = (("jamming_force_n", "jamming_rate_n_per_s", "contact_force_n", "contact_rate_n_per_s")
            if isinstance(clf, ForceRateJammingClassifier) else
            ("drift", "cusum_threshold", "warmup_min_s", "contact_ratio",
             "contact_ratio_rate_per_s"))
    return {k: float(getattr(clf.config, k)) for k in keys}


# --- the suite ------------------------------------------------------------------------------


def _world_rows(train: Mapping[str, list[Movement]], test: Mapping[str, list[Movement]],
                echo: Callable[[str], None]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    drag_fits = {w: _fitted("drag-ratio-jamming", DragRatioJammingConfig(), train[w])
                 for w in WORLDS}
    for world in WORLDS:
        other = next(w for w in WORLDS if w != world)
        entries = {
            "force-rate-jamming defaults": _build("force-rate-jamming",
                                                  ForceRateJammingConfig()),
            "force-rate-jamming fitted here": _fitted(
                "force-rate-jamming", ForceRateJammingConfig(calibration_force_floor="free-drag"),
                train[world]),
            "drag-ratio-jamming defaults": _build("drag-ratio-jamming", DragRatioJammingConfig()),
            "drag-ratio-jamming fitted here": drag_fits[world],
            f"drag-ratio-jamming fitted in {other}": drag_fits[other],
        }
        rows = {}
        for label, clf in entries.items():
            echo(f"jamming-detection: {world}, {label}")
            result = evaluate(_score(clf, test[world]), lambda m: m.labels >= 1,
                              lambda m: m.labels == 0)
            result["thresholds"] = _thresholds(clf)
            if "fitted" in label:
                result["training_report"] = clf.training_report() or None
            rows[label] = result
        out[world] = {"movements": {"train": len(train[world]), "test": len(test[world])},
                      "rows": rows}
    return out


def _real_movements(trials: Sequence[Any]) -> list[Movement]:
    out = []
    for k, trial in enumerate(trials):
        d_m = np.asarray(trial.distance_mm, dtype=np.float64) / 1000.0
        step = np.concatenate([[0.0], np.abs(np.diff(d_m))])
        labels = jamming_labels(trial).astype(np.int64)
        out.append(Movement(trial_batch(trial, t0=100.0 * k), labels, d_m, step, True))
    return out


def _real_rows(echo: Callable[[str], None]) -> dict[str, Any]:
    training, testing = load_trials("training"), load_trials("testing")
    train, test = _real_movements(training), _real_movements(testing)
    speed = float(np.median(np.concatenate([m.step_m[1:] for m in train])) * RATE_HZ)
    common: dict[str, Any] = {"force_channel": "taxel_force", "sample_rate_hz": RATE_HZ,
                              "cutoff_hz": 2.0, "restart_after_gap_s": 0.5}
    drag_common: dict[str, Any] = {**common, "min_drag_n": 1e-3, "settle_window_s": 0.5,
                   "speed_m_per_s": speed}
    entries = {
        "force-rate-jamming fitted here": _fitted(
            "force-rate-jamming", ForceRateJammingConfig(**common), train),
        "drag-ratio-jamming defaults": _build("drag-ratio-jamming",
                                              DragRatioJammingConfig(**drag_common)),
        "drag-ratio-jamming fitted here": _fitted(
            "drag-ratio-jamming", DragRatioJammingConfig(**drag_common), train),
    }

    def far(m: Movement) -> NDArray[np.bool_]:
        return np.asarray(m.distance_m > FAR_MM / 1000.0)

    rows = {}
    for label, clf in entries.items():
        echo(f"jamming-detection: raking-real, {label}")
        scored = _score(clf, test)
        # Free raking is the stretch far from the object; the trials end before contact.
        relabelled = [Movement(m.batch, np.where(far(m), 0, np.maximum(m.labels, 1)),
                               m.distance_m, m.step_m, True) for m in test]
        scored = Scored(scored.scores, scored.flagged, relabelled)
        result = evaluate(scored, lambda m: m.labels >= 1, lambda m: m.labels == 0)
        # ROC: positives within the jamming label, negatives far; the rest left out.
        pos = np.concatenate([m.labels == 1 for m in test])
        neg = np.concatenate([far(m) for m in test])
        scores = np.concatenate(scored.scores)
        keep = pos | neg
        result["roc_auc"] = roc_auc(scores[keep], pos[keep])
        result["roc"] = dict(zip(("fpr", "tpr"), roc_curve(scores[keep], pos[keep]),
                                 strict=True))
        result["thresholds"] = _thresholds(clf)
        if "fitted" in label:
            result["training_report"] = clf.training_report() or None
        rows[label] = result
    return {"movements": {"train": len(train), "test": len(test)}, "speed_m_per_s": speed,
            "rows": rows}


def run_jamming_detection(options: BenchOptions) -> dict[str, Any]:
    """``hapticframe bench jamming-detection`` (see the module docstring); ``--quick``
    uses two depths per world."""
    started = time.perf_counter()
    depths = DEPTHS_M[::3] if options.quick else DEPTHS_M
    train = {w: world_movements(w, "train", options.seed, depths) for w in WORLDS}
    test = {w: world_movements(w, "test", options.seed, depths) for w in WORLDS}
    options.echo(f"jamming-detection: {sum(map(len, train.values()))} training and "
                 f"{sum(map(len, test.values()))} test movements simulated in "
                 f"{time.perf_counter() - started:.1f} s")
    results: dict[str, Any] = _world_rows(train, test, options.echo)
    results["raking-real"] = _real_rows(options.echo)
    load = load_average()
    summary: dict[str, Any] = {
        "command": "hapticframe bench jamming-detection" + (" --quick" if options.quick else "")
        + f" --seed {options.seed}",
        "seed": options.seed, "depths_m": list(depths), "offsets_m": list(OFFSETS_M),
        "speed_m_per_s": SPEED_M_PER_S, "noise_std_n": NOISE_STD_N,
        "budget_false_alarms_per_m": BUDGET_PER_M, "results": results,
        "wall_time_s": time.perf_counter() - started,
        "machine": {"load_average_1min": load},
    }
    out = Path(options.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "jamming-detection.json",
                 json.dumps(summary, indent=1, allow_nan=False) + "\n")
    atomic_write(out / "jamming-detection.md", render_markdown(summary))
    drawn = _figure(out / "jamming-detection.png", summary)
    options.echo(f"wrote {out / 'jamming-detection.md'}"
                 + (" and jamming-detection.png" if drawn else "")
                 + f" in {summary['wall_time_s']:.1f} s")
    options.echo(load_note(load))
    return summary


def _cm(value: float | None) -> str:
    return "–" if value is None else f"{value:.1f} cm"


def _num(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def render_markdown(summary: Mapping[str, Any]) -> str:
    """The report's table: per world and classifier, AUC and the two operating points."""
    lines = [
        "# Jamming detection in units of the sand at hand (issue 32 §1)", "",
        f"Command: `{summary['command']}`; wall time {summary['wall_time_s']:.0f} s.", "",
        f"Simulated worlds: plate at {100 * summary['speed_m_per_s']:g} cm/s, noise "
        f"{summary['noise_std_n']:g} N per axis, depths "
        + ", ".join(f"{100 * d:g}" for d in summary["depths_m"])
        + " cm; approaches aimed 0, 2, 4 cm beside the object; trained on a 3 cm circle, "
        "tested on other seeds with an ellipse and a 2.5 cm circle. Real: 80 raking trials "
        "to fit, 20 to test; free raking farther than 80 mm.", "",
        f"*At budget*: the score threshold with at most {summary['budget_false_alarms_per_m']:g}"
        " false alarm per metre of free raking on the test movements; *own*: the classifier's "
        "arg-max. Distance: from the plate's centre to the object's outline when an approach "
        "is first flagged (median, quartiles); early/late: first flag while the truth is "
        "jamming/contact; missed: never flagged (approaches that pass beside may never touch).",
        "",
        "| data | classifier | ROC AUC | at budget: distance | at budget: early/late/missed | "
        "own: distance | own: early/late/missed | own: false alarms/m |",
        "|---|---|---|---|---|---|---|---|"]
    for data, block in summary["results"].items():
        for label, row in block["rows"].items():
            b, o = row["at_budget"], row["own"]
            bd = b.get("distance_at_first_flag_cm") or {}
            od = o["distance_at_first_flag_cm"]
            budget = (f"{_cm(bd.get('median'))} ({_num(bd.get('q25'), 1)}–"
                      f"{_num(bd.get('q75'), 1)})" if b.get("threshold") is not None else "–")
            counts_b = (f"{b['early']}/{b['late']}/{b['missed']} of {b['approaches']}"
                        if b.get("threshold") is not None else "–")
            lines.append(
                f"| {data} | {label} | {_num(row['roc_auc'], 3)} | {budget} | {counts_b} | "
                f"{_cm(od['median'])} ({_num(od['q25'], 1)}–{_num(od['q75'], 1)}) | "
                f"{o['early']}/{o['late']}/{o['missed']} of {o['approaches']} | "
                f"{_num(o['false_alarms_per_m'])} |")
    lines += ["", "Fitted thresholds:", ""]
    for data, block in summary["results"].items():
        for label, row in block["rows"].items():
            if "fitted" in label:
                lines.append(f"- {data}, {label}: " + ", ".join(
                    f"{k} {v:.4g}" for k, v in row["thresholds"].items()))
    return "\n".join(lines) + "\n"


def _color(label: str) -> str:
    """One colour per classifier and configuration, the same in every panel."""
    if label.startswith("force-rate"):
        return "tab:gray" if "defaults" in label else "tab:brown"
    if "defaults" in label:
        return "tab:blue"
    return "tab:green" if "here" in label else "tab:purple"


def _figure(path: Path, summary: Mapping[str, Any]) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    blocks = summary["results"]
    fig, axes = plt.subplots(1, len(blocks), figsize=(5 * len(blocks), 4.6))
    for ax, (data, block) in zip(np.atleast_1d(axes), blocks.items(), strict=True):
        for label, row in block["rows"].items():
            auc = row["roc_auc"]
            ax.plot(row["roc"]["fpr"], row["roc"]["tpr"], color=_color(label),
                    ls="--" if label.startswith("force-rate") else "-",
                    label=f"{label} (AUC {_num(auc, 3)})")
        ax.plot([0, 1], [0, 1], color="0.7", lw=0.8, label="chance")
        ax.set_xlabel("false-positive rate (free samples flagged)")
        ax.set_ylabel("true-positive rate (jamming/contact samples flagged)")
        ax.set_title(data)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Per-sample ROC of the interaction score on the test movements")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
