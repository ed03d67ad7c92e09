"""The perception example: fit on synthetic trials, then stream one trial into a belief map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe import get_registry
from hapticframe._cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "perception-belief-map.yaml"
FROM_TRAINED = ROOT / "examples" / "perception-from-trained.yaml"

pytest.importorskip("torch")
pytest.importorskip("sklearn")


def test_the_example_trains_first_and_writes_the_timeline_and_snapshots(tmp_path, capsys):
    # The example as shipped, with fewer training trials and epochs to keep the test short.
    text = EXAMPLE.read_text()
    assert "n_trials: 40" in text and "max_epochs: 8" in text
    text = text.replace("n_trials: 40", "n_trials: 6").replace("max_epochs: 8", "max_epochs: 2")
    text = text.replace("../schemas/", str(ROOT / "schemas") + "/")
    path = tmp_path / "perception.yaml"
    path.write_text(text)
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "fitting before the run on 6 recordings of training-trials" in printed

    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "ok"
    assert record["details"]["training"]["trained"] == ["emd", "codes", "sf-rnn"]
    metrics = json.loads((out / "metrics.json").read_text())
    assert 0.0 <= metrics["contact_fraction"] <= 1.0
    # The core scores the SF-RNN against the streamed trial's contact labels (Figure 2.5).
    assert metrics["contact_labels_from"] == "fingertip" and metrics["contact_frames"] > 200
    assert 0.0 <= metrics["contact_balanced_accuracy"] <= 1.0
    names = {p.name for p in out.glob("*.png")}
    assert "labels.png" in names
    assert {"timeline.png", "belief_first_contact.png", "belief_mid_contact.png",
            "belief_last_contact.png"} <= names or (
        # a barely trained network may never decide "contact": then there is no contact to show
        metrics["contact_fraction"] == 0.0 and "timeline.png" in names
    )
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        assert not any(key.startswith("sensor/training-trials/") for key in trace.files)
        frames = len(trace["sensor/fingertip/timestamps_s"])
        probabilities = trace["classifier/sf-rnn/probabilities"]
    assert frames > 200  # one trial of about 3 s at 100 frames/s
    assert probabilities.shape[1] == 2 and np.all(np.isfinite(probabilities))
    assert np.allclose(probabilities.sum(axis=1), 1.0)


def test_trained_once_the_example_runs_from_the_artifacts_without_fitting(tmp_path, monkeypatch):
    # `hapticframe train` on the example saves what `run.train_from` would fit in the run;
    # examples/perception-from-trained.yaml loads those artifacts (from runs/trained, relative
    # to the working directory) and must then classify every frame as the fitting run does,
    # without fitting anything, every time it runs.
    text = EXAMPLE.read_text().replace("n_trials: 40", "n_trials: 4").replace("max_epochs: 8", "max_epochs: 1")
    text = text.replace("../schemas/", str(ROOT / "schemas") + "/")
    # Figures cost time and prove nothing here.
    text = text.replace("  train_from: {fingertip: training-trials}\n",
                        "  train_from: {fingertip: training-trials}\n  figures: false\n")
    assert "figures: false" in text
    fitted_in_run = tmp_path / "fit-in-run.yaml"
    fitted_in_run.write_text(text)
    monkeypatch.chdir(tmp_path)
    assert main(["train", str(fitted_in_run), "--out", "runs/trained"]) == 0
    assert (tmp_path / "runs" / "trained" / "codes" / "dictionaries.npz").is_file()
    assert (tmp_path / "runs" / "trained" / "sf-rnn" / "weights.pt").is_file()

    def _probabilities(out: Path) -> np.ndarray:
        with np.load(out / "trace.npz", allow_pickle=False) as trace:
            return trace["classifier/sf-rnn/probabilities"]

    assert main(["run", str(fitted_in_run), "--out", "fit", "--quiet"]) == 0
    fitted = _probabilities(tmp_path / "fit")

    registry = get_registry()
    for kind, name in (("feature_extractor", "sparse-coding"), ("classifier", "sf-rnn")):
        factory = registry.get(kind, name).spec.load_factory()
        monkeypatch.setattr(factory, "fit", _must_not_fit)
    from_trained = tmp_path / "from-trained.yaml"  # the shipped file, without figures
    from_trained.write_text(FROM_TRAINED.read_text() + "run:\n  figures: false\n")
    assert main(["run", str(from_trained), "--out", "p1", "--quiet"]) == 0
    record = json.loads((tmp_path / "p1" / "run.json").read_text())
    assert record["status"] == "ok" and "training" not in record["details"]
    loaded = _probabilities(tmp_path / "p1")
    assert loaded.shape == fitted.shape and len(fitted) > 200
    np.testing.assert_allclose(loaded, fitted, rtol=0, atol=1e-6)


def _must_not_fit(*args, **kwargs):
    raise AssertionError("a component was fitted in a run that loads its artifacts")
