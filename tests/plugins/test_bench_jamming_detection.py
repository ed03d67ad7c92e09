"""``hapticframe bench jamming-detection`` writes what it promises (a small run)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import BenchOptions

pytestmark = pytest.mark.slow  # about 6 s: two worlds at one depth, 14 real trials


def test_the_suite_scores_both_classifiers_in_every_world(tmp_path: Path, monkeypatch: Any):
    import functools

    import hapticframe_bench._jamming_detection as suite
    import hapticframe_mpm_sand
    from hapticframe_raking import load_trials

    # The engine world's first library, which docs/benchmarks.md's figures were measured in
    # (in the second the absolute thresholds also fire early: a stronger rise).
    first = (Path(hapticframe_mpm_sand.__file__).parent / "data"
             / "response-library-7.5mm-30ms.npz")
    monkeypatch.setattr(hapticframe_mpm_sand, "MpmSandRobotConfig", functools.partial(
        hapticframe_mpm_sand.MpmSandRobotConfig, library_path=str(first)))
    monkeypatch.setattr(suite, "DEPTHS_M", (0.029,))
    monkeypatch.setattr(suite, "load_trials", lambda split: load_trials(split)[:10 if split
                                                                                == "training"
                                                                                else 4])
    lines: list[str] = []
    suite.run_jamming_detection(BenchOptions(tmp_path, echo=lines.append))
    report = json.loads((tmp_path / "jamming-detection.json").read_text())
    assert set(report["results"]) == {"sandbox", "mpm-sand", "raking-real"}
    mpm = report["results"]["mpm-sand"]["rows"]
    assert set(mpm) == {"force-rate-jamming defaults", "force-rate-jamming fitted here",
                        "drag-ratio-jamming defaults", "drag-ratio-jamming fitted here",
                        "drag-ratio-jamming fitted in sandbox"}
    for row in mpm.values():
        assert 0.0 <= row["roc_auc"] <= 1.0
        assert row["own"]["approaches"] == 3
    # The point of the ratio: in the engine world the absolute sandbox thresholds flag the
    # head-on approach only at contact, the drag ratio before it.
    old = mpm["force-rate-jamming defaults"]["own"]
    new = mpm["drag-ratio-jamming defaults"]["own"]
    assert old["early"] == 0 and new["early"] >= 2
    assert new["false_alarms_per_m"] <= 1.0
    budget = mpm["drag-ratio-jamming defaults"]["at_budget"]
    assert budget["false_alarms"] <= budget["free_distance_m"]
    real = report["results"]["raking-real"]["rows"]["drag-ratio-jamming fitted here"]
    assert real["own"]["approaches"] == 4 and np.isfinite(real["roc_auc"])
    markdown = (tmp_path / "jamming-detection.md").read_text()
    assert "| mpm-sand | drag-ratio-jamming defaults |" in markdown
    assert any("wrote" in line for line in lines)
