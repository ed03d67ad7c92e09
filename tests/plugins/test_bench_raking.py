"""The ``raking-real`` and ``raking-jamming`` suites write what they promise (small runs)."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import BenchOptions
from hapticframe_raking import load_trials, selected_settings

pytest.importorskip("h5py")


def test_raking_real_scores_both_and_gives_a_verdict_per_task(tmp_path: Path,
                                                                monkeypatch: Any) -> None:
    pytest.importorskip("torch")
    import hapticframe_bench._raking_real as suite

    # One input set and a tiny network: the suite's plumbing, not its figures.
    monkeypatch.setattr(suite, "INPUT_SETS", {"1_3-axis": None})
    monkeypatch.setattr(suite, "selected_settings", functools.partial(
        selected_settings, epochs=1, hidden_units=4))
    # The Keras check has its own test (test_raking_keras.py); here its report's place.
    monkeypatch.setattr(suite, "keras_check", lambda *a, **k: {"skipped": "not in this test"})
    lines: list[str] = []
    result = suite.run_raking_real(BenchOptions(tmp_path, quick=True, echo=lines.append))
    report = json.loads((tmp_path / "raking-real.json").read_text())
    entry = report["input_sets"]["1_3-axis"]
    assert set(entry["verdicts"]) == {"direction", "depth", "distance", "step_time"}
    distance = entry["comparison"]["distance"]
    for protocol in ("all_steps", "last_step"):
        c = distance[protocol]
        assert c["wins"] + c["ties"] + c["losses"] == 20 and 0.0 <= c["wilcoxon_p"] <= 1.0
        assert c["verdict"] == ("met" if c["mean_met"] and c["median_met"] else "missed")
    assert entry["verdicts"]["distance"] == (
        "met" if all(distance[p]["verdict"] == "met" for p in ("all_steps", "last_step"))
        else "missed")
    assert report["verdicts_met"].endswith("of 3") and report["keras_check"]["skipped"]
    assert len(entry["per_trial"]["names"]) == 20
    # The authors' models are scored as their test_main.py does: a fixed, known result.
    theirs = entry["theirs"]
    assert theirs["direction_accuracy"]["mean"] == pytest.approx(0.354, abs=0.001)
    assert theirs["distance_mae_mm"]["mean"] == pytest.approx(27.3, abs=0.1)
    assert entry["ours_step_ms"] > 0 and entry["theirs_step_ms"] > 0
    markdown = (tmp_path / "raking-real.md").read_text()
    assert "| 1_3-axis | distance MAE (mm) |" in markdown
    assert "| 1_3-axis | distance (mm) | each trial's last step |" in markdown
    assert "Skipped: not in this test" in markdown
    assert result["1_3-axis_distance"] == entry["verdicts"]["distance"]
    assert any(line.startswith("  1_3-axis") for line in lines)


def test_raking_jamming_calibrates_and_scores_the_test_trials(tmp_path: Path) -> None:
    from hapticframe_bench._raking_jamming import (
        JAMMING_MM,
        jamming_labels,
        run_raking_jamming,
        trial_batch,
    )

    trial = load_trials("testing")[0]
    labels = jamming_labels(trial)
    assert labels.dtype == np.int64 and set(np.unique(labels)) == {0, 1}
    assert np.all(trial.distance_mm[labels == 1] <= JAMMING_MM)
    batch = trial_batch(trial, t0=5.0)
    assert batch.timestamps_s[0] == 5.0 and batch.channels["taxel_force"].shape[1:] == (4, 3)
    run_raking_jamming(BenchOptions(tmp_path, echo=lambda _: None))
    report = json.loads((tmp_path / "raking-jamming.json").read_text())
    assert len(report["test"]["per_trial"]) == 20
    assert all(np.isfinite(v) for v in report["thresholds"].values())
    bins = report["premise"]["force_by_distance"]
    assert bins[0]["from_mm"] == 0.0 and sum(b["n"] for b in bins) == sum(
        len(t) for t in load_trials("training") + load_trials("testing"))
    assert "False alarms while far" in (tmp_path / "raking-jamming.md").read_text()


def test_a_verdict_needs_the_mean_and_the_median() -> None:
    from hapticframe_bench._raking_real import _compare

    theirs = np.array([10.0, 10.0, 10.0, 10.0, 10.0])
    # Lower MAE on average, but worse on the median trial: missed.
    mixed = _compare(np.array([0.0, 0.0, 11.0, 11.0, 11.0]), theirs, higher_better=False)
    assert mixed["mean_met"] and not mixed["median_met"] and mixed["verdict"] == "missed"
    assert (mixed["wins"], mixed["ties"], mixed["losses"]) == (2, 0, 3)
    better = _compare(np.array([9.0, 9.0, 10.0, 8.0, 1.0]), theirs, higher_better=False)
    assert better["verdict"] == "met" and (better["wins"], better["ties"]) == (4, 1)
    same = _compare(theirs.copy(), theirs, higher_better=True)
    assert same["verdict"] == "met" and same["ties"] == 5 and same["wilcoxon_p"] == 1.0
    worse = _compare(np.full(5, 0.2), np.full(5, 0.4), higher_better=True)
    assert worse["verdict"] == "missed" and worse["losses"] == 5


def test_the_cv_report_marks_its_choice() -> None:
    from hapticframe_bench._raking_real_cv import render_raking_cv_markdown

    rows = [{"settings": {"range_mm": r, "skip_first_steps": 0, "window_steps": 10},
             "distance_mae_capped_mm": c, "distance_mae_in_range_mm": 20.0,
             "distance_mae_mm": 30.0, "direction_accuracy": 0.3, "depth_accuracy": 0.5}
            for r, c in ((None, 25.0), (100.0, 15.0))]
    text = render_raking_cv_markdown({
        "training_trials": 80, "folds": 4, "seed": 0, "range_mm": 100.0,
        "machine": {"load_average_1min": None},
        "input_sets": {"4_3-axis": {"rows": rows, "chosen": rows[1]["settings"],
                                    "matches_shipped": True}}})
    chosen = [line for line in text.splitlines() if line.endswith("| chosen |")]
    assert len(chosen) == 1 and chosen[0].startswith("| 100.0 | 0 | 10 | 15.0 |")
    assert "Shipped in `SELECTED`: the same." in text
