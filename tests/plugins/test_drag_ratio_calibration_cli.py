"""drag-ratio-jamming calibrated from the CLI, as examples/calibrate-physics-drag.yaml says:
record a search in mpm-sand over a known circle, ``hapticframe train``, search the ellipse
with the fitted thresholds (the train round trip through files)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hapticframe.cli._cli import main

pytestmark = pytest.mark.slow  # about 8 s: two searches and a fit

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_record_train_and_search_with_the_fitted_thresholds(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the example's paths are relative to where it runs
    search = str(EXAMPLES / "search-ellipse-physics-drag.yaml")
    assert main(["run", search, "--out", "runs/recorded-physics-drag", "--quiet",
                 "--set", "run.halt_on_interaction=false", "--set", "run.figures=false",
                 "--set", "scene.objects=[{shape: circle, center_m: [0.25, 0.32], "
                 "radius_m: 0.03}]"]) == 0
    assert main(["train", str(EXAMPLES / "calibrate-physics-drag.yaml"),
                 "--out", "runs/calibrated-physics-drag"]) == 0
    record = json.loads(Path("runs/calibrated-physics-drag/train.json").read_text())
    report = record["reports"]["jamming"]
    assert report["budget_met"] and report["false_alarms_per_m"] <= 1.0
    assert report["early"] >= report["approaches"] // 2 > 0
    saved = json.loads(Path("runs/calibrated-physics-drag/jamming/drag_ratio.json").read_text())
    assert saved["thresholds"]["drift"] == report["drift"]
    assert main(["run", search, "--out", "runs/physics-drag", "--quiet",
                 "--set", "run.figures=false",
                 "--set", "jamming.model_dir=runs/calibrated-physics-drag/jamming"]) == 0
    run = json.loads(Path("runs/physics-drag/run.json").read_text())
    text = json.dumps(run["resolved_config"])
    assert "runs/calibrated-physics-drag/jamming" in text
