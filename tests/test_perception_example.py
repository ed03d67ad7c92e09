"""The perception example: fit on synthetic trials, then stream one trial into a belief map."""

from __future__ import annotations

import json
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
    names = {p.name for p in out.glob("*.png")}
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
