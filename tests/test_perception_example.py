"""The perception example: fit on synthetic trials, then stream one trial into a belief map."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from hapticframe._cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "perception-belief-map.yaml"

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


def test_saved_artifacts_reproduce_the_run_time_fit(tmp_path):
    # `hapticframe train` on the example saves what `run.train_from` would fit in the run;
    # a run that loads those artifacts must then classify every frame identically.
    text = EXAMPLE.read_text()
    text = text.replace("n_trials: 40", "n_trials: 4").replace("max_epochs: 8", "max_epochs: 1")
    text = text.replace("../schemas/", str(ROOT / "schemas") + "/")
    fitted_in_run = tmp_path / "fit-in-run.yaml"
    fitted_in_run.write_text(text)
    assert main(["train", str(fitted_in_run), "--out", str(tmp_path / "artifacts")]) == 0
    assert (tmp_path / "artifacts" / "codes" / "dictionaries.npz").is_file()
    assert (tmp_path / "artifacts" / "sf-rnn" / "weights.pt").is_file()

    codes, sf_rnn = tmp_path / "artifacts" / "codes", tmp_path / "artifacts" / "sf-rnn"
    loaded = text.replace(
        "config: {amplitude: channel}",
        f"config: {{amplitude: channel, dictionary_file: '{codes}'}}",
    )
    loaded = loaded.replace(
        "config: {max_epochs: 1, amplitude_inputs: true}",
        f"config: {{amplitude_inputs: true, model_dir: '{sf_rnn}'}}",
    )
    loaded = loaded.replace(
        "  train_from: {fingertip: training-trials}\n", "  label_channel: contact\n"
    )
    training_sensor = r"  - id: training-trials\n    type: biotac\n    config: \{[^}]*\}\n"
    loaded = re.sub(training_sensor, "", loaded)
    assert "training-trials" not in loaded.split("sensors:")[1]
    assert "train_from: {" not in loaded and "dictionary_file" in loaded and "model_dir" in loaded
    from_files = tmp_path / "from-files.yaml"
    from_files.write_text(loaded)

    runs = {}
    for name, path in (("fit", fitted_in_run), ("files", from_files)):
        out = tmp_path / name
        assert main(["run", str(path), "--out", str(out), "--quiet"]) == 0
        with np.load(out / "trace.npz", allow_pickle=False) as trace:
            runs[name] = trace["classifier/sf-rnn/probabilities"]
    assert runs["fit"].shape == runs["files"].shape and len(runs["fit"]) > 200
    np.testing.assert_allclose(runs["files"], runs["fit"], rtol=0, atol=1e-6)
