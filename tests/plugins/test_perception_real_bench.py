"""``hapticframe bench perception-real`` and ``biotac-calibration`` on small files in the
BOLT layout (the real files stay outside the repository)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("h5py")
pytest.importorskip("torch")

from hapticframe import BenchOptions, UsageError
from hapticframe.cli._cli import main
from hapticframe_bench._biotac_calibration import run_biotac_calibration
from hapticframe_bench._perception_models import Architecture
from hapticframe_bench._perception_real import RealPlan, run_perception_real, score_object
from hapticframe_biotac import BioTacCalibration
from tests.support.bolt_fixture import write_bolt_dir


def test_score_object_against_hand_counts() -> None:
    truth = [np.array([0, 0, 0, 0, 1, 1, 1, 1, 0, 0]), np.array([0, 0, 1, 1, 0, 0])]
    proba = [np.array([.1, .2, .1, .6, .4, .7, .9, .8, .3, .1]),
             np.array([.1, .2, .3, .9, .2, .1])]
    row = score_object(truth, proba, threshold=0.5, specificity=0.9)
    # Free frames: 10, one above 0.5 (0.6): specificity 0.9; contact 6, 4 above 0.5.
    assert row["balanced_accuracy"] == pytest.approx((0.9 + 4 / 6) / 2)
    # The lowest cut keeping 9 of the 10 free frames at or below it is 0.3; 5 of 6 contact
    # frames exceed it.
    assert row["threshold_at_specificity"] == pytest.approx(0.3)
    assert row["recall_at_specificity"] == pytest.approx(5 / 6)
    # First contact read 1 frame late in the first recording, 1 frame in the second.
    assert row["first_contact_delay_s"] == pytest.approx(0.01)
    assert row["missed_contacts"] == 0 and row["frames"] == 16
    missed = score_object([np.array([0, 1, 1])], [np.array([.1, .2, .3])], 0.5)
    assert missed["missed_contacts"] == 1 and missed["first_contact_delay_s"] is None


@pytest.fixture(scope="module")
def bolt_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_bolt_dir(tmp_path_factory.mktemp("bolt"), ("cork", "foam", "metal_bar"),
                          count=3, n=250, seed=2)


def test_perception_real_scores_every_object_with_and_without_pdc(bolt_dir: Path,
                                                                  tmp_path: Path) -> None:
    plan = RealPlan(recordings_per_object=2, calibration_trials_per_object=1,
                    synthetic_trials=0, press_trials=3, max_epochs=1, patience=1,
                    coder_fit_frames=100, sources=("calibrated", "calibrated-loo", "real-loo"),
                    architectures=(Architecture("b", "svm"), Architecture("d", "svm")),
                    svm_settings={"calibration_folds": 2, "max_iter": 50},
                    coder_settings={"fit_epochs": 1, "amplitude": "channel",
                                    "pac_atoms": 16, "pdc_atoms": 8, "electrodes_atoms": 8})
    lines: list[str] = []
    result = run_perception_real(BenchOptions(out_dir=tmp_path, data=bolt_dir, workers=1,
                                              echo=lines.append), plan)
    rows = result["results"]
    cells = {(r["source"], r["model"], r["inputs"], r["object"]) for r in rows}
    assert len(cells) == len(rows) == 3 * 2 * 2 * 3
    assert {r["inputs"] for r in rows} == {"with pdc", "without pdc"}
    for r in rows:
        assert 0.0 <= r["balanced_accuracy"] <= 1.0 and r["recordings"] == 4
    # The calibration trials are never scored.
    for obj, scored in result["scored_trials"].items():
        assert not set(scored) & set(result["calibration"]["trials"][obj])
    # Easy fixture presses: the real-trained SVM finds them on the held-out object.
    loo = [r for r in rows if r["source"] == "real-loo" and r["model"] == "(b)+Linear SVM"]
    assert min(r["balanced_accuracy"] for r in loo) > 0.8
    saved = json.loads((tmp_path / "perception-real.json").read_text())
    assert saved["reference"]["name"] == "derived from pdc"
    text = (tmp_path / "perception-real.md").read_text()
    assert "derived from pdc" in text and "without pdc" in text and "| cork |" in text
    assert any("leave out metal_bar" in line for line in lines)
    assert (tmp_path / "perception-real.png").stat().st_size > 10_000


def test_perception_real_needs_data(tmp_path: Path, capsys: Any) -> None:
    with pytest.raises(UsageError, match="needs --data"):
        run_perception_real(BenchOptions(out_dir=tmp_path))
    assert main(["bench", "perception-real", "--data", str(tmp_path / "none"),
                 "--out", str(tmp_path / "o")]) == 2
    assert "not a directory of BOLT .h5 files" in capsys.readouterr().err


def test_biotac_calibration_writes_the_generators_parameters(bolt_dir: Path,
                                                             tmp_path: Path) -> None:
    result = run_biotac_calibration(BenchOptions(out_dir=tmp_path, data=bolt_dir, quick=True,
                                                 trials=2))
    cal = BioTacCalibration.load(tmp_path / "biotac-calibration.json")
    assert cal.recordings == result["recordings"] == 12
    stats = result["statistics"]
    assert stats["real"]["rest_pdc"] == pytest.approx(1800, abs=2)
    assert stats["calibrated generator"]["rest_pdc"] == pytest.approx(1800, abs=10)
    assert abs(stats["uncalibrated generator"]["rest_pdc"] - 1800) > 50
    assert "| resting pdc (counts) |" in (tmp_path / "biotac-calibration.md").read_text()
