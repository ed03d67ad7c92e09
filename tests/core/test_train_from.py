"""``run.train_from``: fit the trainable components on training sensors before a run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe._cli import main

from tests.support.lab import lab_main, validate_lab
from hapticframe._config import validate_file
from hapticframe._errors import ExperimentError

EXPERIMENT = """\
schema_version: 1
name: lab-train-from
seed: 3
scene:
  objects:
    - {shape: circle, center_m: [0.40, 0.25], radius_m: 0.03}
sensors:
  - id: sweep
    type: lab-sweep
    config: {samples: 300, chunk: 20}
  - id: rehearsal
    type: lab-sweep
    config: {samples: 200, chunk: 50, peak_n: 90.0}
classifiers:
  - id: contact
    type: lab-threshold
    inputs: [sweep]
    config: {threshold_n: 200.0}
sensor_models:
  - {id: point, type: lab-point, inputs: [contact]}
maps:
  - {id: cells, type: lab-cells, inputs: [point]}
run:
  train_from: {sweep: rehearsal}
"""


def _write(lab_dir: Path, text: str) -> Path:
    path = lab_dir / "train-from.yaml"
    path.write_text(text)
    return path


def test_components_are_fitted_on_the_training_sensor_before_the_run(lab_dir):
    out = lab_dir / "run"
    assert lab_main(["run", str(_write(lab_dir, EXPERIMENT)), "--out", str(out), "--quiet"]) == 0
    training = json.loads((out / "run.json").read_text())["details"]["training"]
    assert training["recordings"] == 1 and training["trained"] == ["contact"]
    # Fitted on the 90 N rehearsal sweep, the threshold sits between its free and contact
    # forces (about 39 N): far below the configured 200 N, and above the about 20 N that the
    # 40 N sweep itself would give.
    threshold = training["reports"]["contact"]["threshold_n"]
    assert 30.0 < threshold < 60.0
    with np.load(out / "trace.npz") as trace:
        assert not any(key.startswith("sensor/rehearsal/") for key in trace.files)
        assert trace["sensor/sweep/force_n"].shape == (300, 2)
        decided = trace["classifier/contact/probabilities"][:, 1] > 0.5
    # With the configured 200 N threshold nothing would count as contact.
    assert decided.any()


def test_train_uses_the_training_sensor_in_place_of_the_streamed_one(lab_dir):
    out = lab_dir / "trained"
    assert lab_main(["train", str(_write(lab_dir, EXPERIMENT)), "--out", str(out)]) == 0
    record = json.loads((out / "train.json").read_text())
    assert record["recordings"] == 1
    assert 30.0 < record["reports"]["contact"]["threshold_n"] < 60.0


@pytest.mark.parametrize(
    ("train_from", "message"),
    [
        ("{sweeps: rehearsal}", "key 'sweeps' is not the id of a sensor; did you mean 'sweep'?"),
        ("{sweep: contact}", "value 'contact' is not the id of a sensor"),
        ("{sweep: sweep}", "cannot stand in for itself"),
        ("{sweep: rehearsal, rehearsal: sweep}", "is both streamed and a training sensor"),
    ],
)
def test_bad_train_from_is_located(lab_dir, train_from, message):
    text = EXPERIMENT.replace("train_from: {sweep: rehearsal}", f"train_from: {train_from}")
    with pytest.raises(ExperimentError) as caught:
        validate_lab(_write(lab_dir, text))
    assert message in str(caught.value)
    assert "run.train_from" in str(caught.value)


def test_a_training_sensor_may_not_feed_the_run(lab_dir):
    text = EXPERIMENT.replace("inputs: [sweep]", "inputs: [rehearsal]")
    with pytest.raises(ExperimentError) as caught:
        validate_lab(_write(lab_dir, text))
    assert "training sensor 'rehearsal' is an input of 'contact'" in str(caught.value)


def test_a_failing_fit_names_its_component(lab_dir, monkeypatch, capsys):
    import importlib

    monkeypatch.syspath_prepend(str(lab_dir))
    labplugin = importlib.import_module("labplugin")  # the module the run will use

    def refuse(self, batches, labels):  # type: ignore[no-untyped-def]
        raise ValueError("no contact frames to learn from")

    monkeypatch.setattr(labplugin.ThresholdClassifier, "fit", refuse)
    path = _write(lab_dir, EXPERIMENT)
    assert lab_main(["run", str(path), "--out", str(lab_dir / "run"), "--quiet"]) == 1
    assert lab_main(["train", str(path), "--out", str(lab_dir / "trained")]) == 1
    err = capsys.readouterr().err
    located = "fitting contact (lab-threshold) failed: ValueError: no contact frames to learn from"
    assert err.count(located) == 2
    assert "Traceback" not in err
