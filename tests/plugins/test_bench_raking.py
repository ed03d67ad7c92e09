"""The ``raking-real`` and ``raking-jamming`` suites write what they promise (small runs)."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import BenchOptions
from hapticframe_raking import EstimatorSettings, load_trials

pytest.importorskip("h5py")


def test_raking_real_scores_both_and_gives_a_verdict_per_task(tmp_path: Path,
                                                                monkeypatch: Any) -> None:
    pytest.importorskip("torch")
    import hapticframe_bench._raking_real as suite

    # One input set and a tiny network: the suite's plumbing, not its figures.
    monkeypatch.setattr(suite, "INPUT_SETS", {"1_3-axis": None})
    monkeypatch.setattr(suite, "EstimatorSettings", functools.partial(
        EstimatorSettings, epochs=1, hidden_units=4))
    lines: list[str] = []
    result = suite.run_raking_real(BenchOptions(tmp_path, quick=True, echo=lines.append))
    report = json.loads((tmp_path / "raking-real.json").read_text())
    entry = report["input_sets"]["1_3-axis"]
    assert set(entry["verdicts"]) == {"direction", "depth", "distance", "step_time"}
    assert len(entry["per_trial"]["names"]) == 20
    # The authors' models are scored as their test_main.py does: a fixed, known result.
    theirs = entry["theirs"]
    assert theirs["direction_accuracy"]["mean"] == pytest.approx(0.354, abs=0.001)
    assert theirs["distance_mae_mm"]["mean"] == pytest.approx(27.3, abs=0.1)
    assert entry["ours_step_ms"] > 0 and entry["theirs_step_ms"] > 0
    markdown = (tmp_path / "raking-real.md").read_text()
    assert "| 1_3-axis | distance MAE (mm) |" in markdown
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
