"""``hapticframe bench perception-real --data DIR``: contact detection on real BioTac trials.

Data: the Penn BOLT recordings (``DIR/*.h5``, one file per object, both fingertips of a
PR2 gripper pressing, holding and releasing an object; ``hapticframe_biotac.load_bolt``).
They carry no contact labels, so the reference is **derived from pdc**
(``hapticframe_biotac.derived_from_pdc``: contact from a rise of more than 20 counts above
the first second's resting level until the rise falls below 10). Because the reference is
read off pdc, every model is trained and scored twice: with all three modalities, and
**without pdc** (pac and electrodes only), so that the comparison is not circular.

Per object (``recordings_per_object`` trials, both fingers), each of three architectures
of the perception bench — the SF-RNN and the (b) and (d) linear SVM baselines — is trained
on

- ``synthetic``: the synthetic granular-media rakes of ``bench perception`` (cottonwood,
  zeroed in air), uncalibrated;
- ``calibrated``: synthetic press trials from the generator calibrated on real recordings
  that are never scored (``calibration_trials_per_object`` other trials of every object;
  ``hapticframe_biotac.calibrate_biotac``), none of the scored ones;
- ``calibrated-loo``: the same, calibrated on the calibration trials of the *other* objects
  only (no recording of the scored object informs its model);
- ``real-loo``: the scored real trials of the other objects (leave one object out);

and scored by balanced accuracy over the object's frames, recall at
``SPECIFICITY`` (the threshold on p(contact) that keeps that share of the free frames
free) and the first-contact delay (median over recordings of the frames from the
reference's first contact to the first frame read as contact within it; recordings whose
contact is never read are counted as missed). Every recording is zeroed on its first 100
frames (1 s at rest in air). ``--quick`` runs :data:`QUICK_REAL_PLAN`, else
:data:`REAL_PLAN`; ``--trials N`` scores N trials per object; ``--seed`` draws the scored and
the calibration trials and seeds every model. Outputs: ``perception-real.json``,
``perception-real.md`` and ``perception-real.png`` (balanced accuracy per object).
"""

from __future__ import annotations

import json
import os
import platform
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, UsageError, atomic_write

from ._perception import QUICK_PLAN
from ._perception_data import TrialFeatures, build_perception_data
from ._perception_models import Architecture, TrainedModel, _batch, train_architecture
from ._perception_real_data import (
    as_data,
    code_trials,
    fit_coder,
    press_features,
    real_features,
)
from ._perception_real_report import render_real_markdown, save_real_figure

__all__ = ["QUICK_REAL_PLAN", "REAL_PLAN", "RealPlan", "run_perception_real", "score_object"]

#: The specificity at which recall is reported.
SPECIFICITY = 0.95
ARCHITECTURES = (Architecture("d", "rnn"), Architecture("b", "svm"), Architecture("d", "svm"))
MODALITY_SETS = {"with pdc": ("pac", "pdc", "electrodes"),
                 "without pdc": ("pac", "electrodes")}
SOURCES = ("synthetic", "calibrated", "calibrated-loo", "real-loo")


@dataclass(frozen=True)
class RealPlan:
    """Sizes of one run. ``recordings_per_object`` None scores every trial not used for
    calibration."""

    recordings_per_object: int | None
    calibration_trials_per_object: int
    synthetic_trials: int
    press_trials: int
    max_epochs: int
    patience: int
    coder_fit_frames: int
    tare_frames: int = 100
    reference: dict[str, Any] = field(default_factory=lambda: {
        "rest_frames": 100, "on_counts": 20.0, "off_counts": 10.0})
    rnn_settings: dict[str, Any] = field(default_factory=lambda: dict(QUICK_PLAN.rnn_settings))
    svm_settings: dict[str, Any] = field(default_factory=lambda: dict(QUICK_PLAN.svm_settings))
    coder_settings: dict[str, Any] = field(
        default_factory=lambda: dict(QUICK_PLAN.coder_settings))
    sources: tuple[str, ...] = SOURCES
    architectures: tuple[Architecture, ...] = ARCHITECTURES
    #: The recurrent models' window step over the long press trials (real and calibrated,
    #: about 5,000 frames each, mostly holds): every 50 frames keeps their training windows
    #: (50 frames each) to ~100 per trial instead of ~1,000 (memory: GBs).
    long_trial_stride_frames: int = 50

    def as_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if k != "architectures"}
        out["architectures"] = [a.label for a in self.architectures]
        out["sources"] = list(self.sources)
        return out


#: Two trials per object (both fingers: four recordings, about 20,000 frames), two others
#: per object for the calibration, 16 calibrated press trials (about 75,000 frames).
QUICK_REAL_PLAN = RealPlan(recordings_per_object=2, calibration_trials_per_object=2,
                           synthetic_trials=45, press_trials=16, max_epochs=6, patience=3,
                           coder_fit_frames=2000)
#: Every trial but three per object (kept for the calibration) scored.
REAL_PLAN = RealPlan(recordings_per_object=None, calibration_trials_per_object=3,
                     synthetic_trials=150, press_trials=120, max_epochs=15, patience=4,
                     coder_fit_frames=10000)


def _choose_trials(trials: Sequence[Any], plan: RealPlan, seed: int
                   ) -> tuple[dict[str, list[str]], dict[str, list[str]]]:
    """Per object, the trials scored and the (other) trials the calibration reads, drawn
    by a seeded permutation."""
    names: dict[str, list[str]] = {}
    for t in trials:
        names.setdefault(t.object, [])
        if t.trial not in names[t.object]:
            names[t.object].append(t.trial)
    scored, calibration = {}, {}
    for k, (obj, found) in enumerate(sorted(names.items())):
        order = np.random.default_rng(np.random.SeedSequence([seed, 29, k])).permutation(
            len(found))
        shuffled = [found[i] for i in order]
        n_cal = min(plan.calibration_trials_per_object, max(0, len(found) - 1))
        calibration[obj] = sorted(shuffled[:n_cal])
        rest = shuffled[n_cal:]
        scored[obj] = sorted(rest if plan.recordings_per_object is None
                             else rest[: plan.recordings_per_object])
    return scored, calibration


def probabilities(model: TrainedModel, trial: TrialFeatures) -> np.ndarray:
    """p(contact) of every frame of ``trial``."""
    batch = _batch(trial, model.architecture, model.modalities, model.amplitude_modalities)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        predict = getattr(model.component, "predict_sequence", model.component.predict_proba)
        proba = predict(batch)
    return np.asarray(proba.probabilities, dtype=np.float64)[:, 1]


def score_object(truth: Sequence[np.ndarray], proba: Sequence[np.ndarray], threshold: float,
                 specificity: float = SPECIFICITY) -> dict[str, Any]:
    """Balanced accuracy, recall at ``specificity`` and first-contact delay of one object's
    recordings (``truth`` labels and ``proba`` p(contact) per recording)."""
    from hapticframe_sfrnn import balanced_accuracy, contact_figures

    y = np.concatenate(truth).astype(np.int64)
    p = np.concatenate(proba)
    predicted = [(q > threshold).astype(np.int64) for q in proba]
    figures = contact_figures(list(truth), predicted)
    free, contact = p[y == 0], p[y == 1]
    recall = None
    cut = None
    if free.size and contact.size:
        # The lowest cut that keeps at least ``specificity`` of the free frames at or below.
        ordered = np.sort(free)
        cut = float(ordered[max(0, int(np.ceil(specificity * free.size - 1e-9)) - 1)])
        recall = float(np.mean(contact > cut))
    delay = figures["onset_delay_frames"]
    return {
        "balanced_accuracy": balanced_accuracy(y, (p > threshold).astype(np.int64)),
        "recall_at_specificity": recall, "specificity": specificity,
        "threshold_at_specificity": cut,
        "contact_recall": figures["contact_recall"],
        "free_specificity": figures["free_specificity"],
        "first_contact_delay_s": None if delay is None else 0.01 * float(delay),
        "missed_contacts": figures["missed_contacts"],
        "contact_recordings": figures["contact_trials"], "recordings": len(truth),
        "frames": int(y.size), "contact_fraction": float(y.mean()) if y.size else 0.0,
    }


def _train_all(data: Any, plan: RealPlan, seed: int, say: Callable[[str], None],
               long_trials: bool = True) -> dict[tuple[str, str], TrainedModel]:
    rnn = {**plan.rnn_settings, "max_epochs": plan.max_epochs, "patience": plan.patience}
    if long_trials:
        rnn.update(free_stride_frames=plan.long_trial_stride_frames,
                   contact_stride_frames=plan.long_trial_stride_frames)
    models = {}
    for arch in plan.architectures:
        for label, mods in MODALITY_SETS.items():
            model = train_architecture(data, arch, mods, seed, rnn, plan.svm_settings)
            models[arch.label, label] = model
            say(f"  trained {arch.label}, {label}: {model.train_time_s:.0f} s")
    return models


def _score_models(models: dict[tuple[str, str], TrainedModel], source: str, obj: str,
                  trials: Sequence[TrialFeatures], rows: list[dict[str, Any]]) -> None:
    for (arch, label), model in models.items():
        proba = [probabilities(model, t) for t in trials]
        row = score_object([t.labels for t in trials], proba, model.contact_threshold)
        rows.append({"source": source, "model": arch, "inputs": label, "object": obj, **row,
                     "train_time_s": model.train_time_s})


def _summary_lines(rows: Sequence[dict[str, Any]], source: str) -> list[str]:
    """One progress line per model and inputs: balanced accuracy per object."""
    cells: dict[tuple[str, str], list[str]] = {}
    for r in rows:
        if r["source"] == source:
            cells.setdefault((r["model"], r["inputs"]), []).append(
                f"{r['object']} {r['balanced_accuracy']:.3f}")
    return [f"  {source} {model}, {inputs}: {', '.join(v)}"
            for (model, inputs), v in cells.items()]


def run_real_suite(data_dir: Path, plan: RealPlan, seed: int, workers: int,
                   say: Callable[[str], None]) -> dict[str, Any]:
    """Load, featurise, train and score (see the module notes); the result as a dict."""
    from hapticframe_biotac import (
        DERIVED_FROM_PDC,
        ReplayFormatError,
        calibrate_biotac,
        load_bolt_dir,
    )

    timing: dict[str, float] = {}
    started = time.perf_counter()
    try:
        trials = load_bolt_dir(data_dir)
    except ReplayFormatError as exc:
        raise UsageError(f"--data: {exc}") from exc
    scored, calibration_trials = _choose_trials(trials, plan, seed)
    objects = sorted(scored)
    if len(objects) < 2:
        raise UsageError(f"--data {data_dir}: leave-one-object-out needs at least two "
                         f"objects (files), found {len(objects)}")
    recordings = [(str(t.recording.metadata["source"]), t.object, t.trial, t.finger)
                  for t in trials if t.trial in scored[t.object]]
    say(f"perception-real: {len(objects)} objects, {len(recordings)} scored recordings "
        f"({sum(len(v) for v in scored.values())} trials, both fingers), seed {seed}")
    real = real_features(recordings, plan.reference, plan.tare_frames, workers, {}, say)
    timing["real_features"] = time.perf_counter() - started
    rows: list[dict[str, Any]] = []
    calibration_summary: dict[str, Any] | None = None

    if "synthetic" in plan.sources:
        t0 = time.perf_counter()
        say(f"(a) synthetic granular rakes: {plan.synthetic_trials} trials")
        synth = build_perception_data(
            cottonwood_trials=plan.synthetic_trials, robustness_per_medium=1, seed=seed,
            workers=workers, tare_frames=10, tare_source="air",
            coder_fit_frames=plan.coder_fit_frames, coder_settings=plan.coder_settings,
            echo=say)
        models = _train_all(synth, plan, seed, say, long_trials=False)
        coded = code_trials(real, synth.coder)
        del synth
        for obj in objects:
            _score_models(models, "synthetic", obj, [t for t in coded if t.medium == obj], rows)
        timing["synthetic"] = time.perf_counter() - t0
        say(f"(a) done in {timing['synthetic']:.0f} s; balanced accuracy:")
        for line in _summary_lines(rows, "synthetic"):
            say(line)

    if "calibrated" in plan.sources:
        t0 = time.perf_counter()
        chosen = [t for t in trials if t.trial in calibration_trials[t.object]]
        calibration = calibrate_biotac([t.frames for t in chosen], [t.finger for t in chosen],
                                       **_calibration_reference(plan))
        calibration_summary = {"trials": {o: v for o, v in calibration_trials.items()},
                               "parameters": calibration.as_dict()}
        say(f"(a') calibrated press trials: {plan.press_trials}, calibrated on "
            f"{len(chosen)} other recordings")
        press = press_features(calibration, plan.press_trials, seed, plan.reference,
                               plan.tare_frames, workers, {}, say)
        coder = fit_coder([t for t in press if t.split == "train"], plan.coder_settings,
                          plan.coder_fit_frames, seed)
        models = _train_all(as_data(code_trials(press, coder), coder, plan.tare_frames),
                            plan, seed, say)
        del press
        coded = code_trials(real, coder)
        for obj in objects:
            _score_models(models, "calibrated", obj, [t for t in coded if t.medium == obj],
                          rows)
        timing["calibrated"] = time.perf_counter() - t0
        say(f"(a') done in {timing['calibrated']:.0f} s; balanced accuracy:")
        for line in _summary_lines(rows, "calibrated"):
            say(line)

    if "calibrated-loo" in plan.sources:
        t0 = time.perf_counter()
        for k, obj in enumerate(objects):
            chosen = [t for t in trials
                      if t.object != obj and t.trial in calibration_trials[t.object]]
            calibration = calibrate_biotac([t.frames for t in chosen],
                                           [t.finger for t in chosen],
                                           **_calibration_reference(plan))
            press = press_features(calibration, plan.press_trials, seed, plan.reference,
                                   plan.tare_frames, workers, {}, lambda _line: None)
            coder = fit_coder([t for t in press if t.split == "train"], plan.coder_settings,
                              plan.coder_fit_frames, seed)
            models = _train_all(as_data(code_trials(press, coder), coder, plan.tare_frames),
                                plan, seed, lambda _line: None)
            del press
            _score_models(models, "calibrated-loo", obj,
                          code_trials([t for t in real if t.medium == obj], coder), rows)
            say(f"(a'') calibrated without {obj}: {k + 1}/{len(objects)}, "
                f"{time.perf_counter() - t0:.0f} s")
        timing["calibrated_loo"] = time.perf_counter() - t0
        for line in _summary_lines(rows, "calibrated-loo"):
            say(line)

    if "real-loo" in plan.sources:
        t0 = time.perf_counter()
        for k, obj in enumerate(objects):
            others = [t for t in real if t.medium != obj]
            # One trial (both fingers) of each other object stops the recurrent training.
            first: dict[str, str] = {}
            for t in others:
                first.setdefault(t.medium, recordings[t.index][2])
            def split(t: TrialFeatures, held: str = obj, val: dict[str, str] = first) -> str:
                if t.medium == held:
                    return "test"
                return "validation" if recordings[t.index][2] == val[t.medium] else "train"
            coder = fit_coder([t for t in others if split(t) == "train"], plan.coder_settings,
                              plan.coder_fit_frames, seed)
            fold = code_trials(real, coder, split)
            models = _train_all(as_data(fold, coder, plan.tare_frames), plan, seed, say)
            _score_models(models, "real-loo", obj, [t for t in fold if t.split == "test"], rows)
            say(f"(b) leave out {obj}: {k + 1}/{len(objects)}, "
                f"{time.perf_counter() - t0:.0f} s")
        timing["real_loo"] = time.perf_counter() - t0
    timing["total_wall"] = time.perf_counter() - started
    return {
        "reference": {**plan.reference, "name": DERIVED_FROM_PDC,
                      "rule": "contact from a rise of more than on_counts above the mean of "
                              "the first rest_frames raw pdc frames until the rise falls "
                              "below off_counts"},
        "objects": objects, "scored_trials": scored, "recordings": len(recordings),
        "frames": int(sum(len(t) for t in real)),
        "contact_fraction": float(np.mean(np.concatenate([t.labels for t in real]))),
        "calibration": calibration_summary, "plan": plan.as_dict(), "seed": seed,
        "results": rows, "timing_s": timing,
    }


def _calibration_reference(plan: RealPlan) -> dict[str, Any]:
    return {"reference": dict(plan.reference)}


def run_perception_real(options: BenchOptions, plan: RealPlan | None = None) -> dict[str, Any]:
    """``hapticframe bench perception-real --data DIR``: perception-real.json and .md."""
    if options.data is None:
        raise UsageError("perception-real needs --data DIR (a directory of Penn BOLT .h5 "
                         "files, e.g. shared/realdata/penn-bolt-biotac)")
    if options.trials is not None:
        base = plan or (QUICK_REAL_PLAN if options.quick else REAL_PLAN)
        plan = RealPlan(**{**base.__dict__, "recordings_per_object": int(options.trials)})
    plan = plan or (QUICK_REAL_PLAN if options.quick else REAL_PLAN)
    workers = int(options.workers or min(os.cpu_count() or 1, 8))
    load_before = os.getloadavg()[0]
    result = run_real_suite(Path(options.data), plan, options.seed, workers, options.echo)
    result["machine"] = {"platform": platform.platform(), "cpus": os.cpu_count(),
                         "python": platform.python_version(), "workers": workers,
                         "load_average_1min_start": load_before,
                         "load_average_1min_end": os.getloadavg()[0]}
    result["command"] = ("hapticframe bench perception-real --data DIR"
                         + (" --quick" if options.quick else "")
                         + (f" --trials {options.trials}" if options.trials else "")
                         + f" --seed {options.seed}")
    out = Path(options.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "perception-real.json",
                 json.dumps(result, indent=2, allow_nan=False) + "\n")
    atomic_write(out / "perception-real.md", render_real_markdown(result))
    save_real_figure(result, out / "perception-real.png")
    options.echo(f"perception-real: {len(result['results'])} scores in "
                 f"{result['timing_s']['total_wall']:.0f} s; {out / 'perception-real.md'}")
    return result
