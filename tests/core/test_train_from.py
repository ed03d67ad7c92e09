"""``run.train_from``: fit the trainable components on training sensors before a run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe._errors import ExperimentError
from hapticframe.cli._cli import main
from tests.support.lab import lab_main, validate_lab

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


# The README's perception example (examples/perception-belief-map.yaml) made tiny: a few
# short training trials, one epoch, small networks; every bundled trainable plugin that
# reads BioTac frames is in it (the jamming classifier, which reads a force, is checked
# below on its own).
TINY_PERCEPTION = """\
schema_version: 1
name: tiny-perception
seed: 3
sensors:
  - id: fingertip
    type: biotac
    config: {source: synthetic, medium: cottonwood_beads, speed_m_per_s: 0.04, has_object: true,
             tare_frames: 10, tare_source: air}
  - id: training-trials
    type: biotac
    config: {source: synthetic, dataset: training, n_trials: 3, tare_frames: 10, tare_source: air}
feature_extractors:
  - {id: emd, type: emd-features, inputs: [fingertip]}
  - id: codes
    type: sparse-coding
    inputs: [emd]
    config: {fit_epochs: 1, pac_atoms: 8, pdc_atoms: 4, electrodes_atoms: 8}
classifiers:
  - id: sf-rnn
    type: sf-rnn
    inputs: [codes]
    config: {max_epochs: 1, gru_units: 4, progress: false, pac_code_size: 8, pdc_code_size: 4,
             electrodes_code_size: 8}
  - id: fusion
    type: fusion-rnn
    inputs: [codes]
    config: {max_epochs: 1, branch_units: 4, fusion_units: 4, progress: false, pac_code_size: 8,
             pdc_code_size: 4, electrodes_code_size: 8}
  - id: svm
    type: linear-svm
    inputs: [fingertip]
    config: {inputs: {pac: 22, pdc: 1, electrodes: 19}}
run:
  train_from: {fingertip: training-trials}
"""


@pytest.mark.slow  # about 8 s: torch, EMD and trial synthesis for every model
def test_train_json_reports_on_every_bundled_trainable_plugin(tmp_path):
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY_PERCEPTION)
    out = tmp_path / "trained"
    assert main(["train", str(path), "--out", str(out)]) == 0
    record = json.loads((out / "train.json").read_text())
    assert record["trained"] == ["emd", "codes", "sf-rnn", "fusion", "svm"]
    reports = record["reports"]
    assert reports["emd"] is None  # EMD features learn nothing: not Trainable
    for cid in ("codes", "sf-rnn", "fusion", "svm"):
        assert isinstance(reports[cid], dict) and reports[cid], cid
    assert reports["svm"]["train_trials"] == 3
    assert reports["sf-rnn"]["epochs"] >= 1
    assert set(reports["codes"]["modalities"]) == {"pac", "pdc", "electrodes"}
    assert set(record["artifacts"]) == {"codes", "sf-rnn", "fusion", "svm"}  # Persistent
    assert record["versions"]["numpy"] == np.__version__ and "git_commit" in record["versions"]


def test_the_jamming_classifier_reports_the_thresholds_it_learned():
    from hapticframe.kinds import BuildContext, SampleBatch, Trainable
    from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig

    classifier = ForceRateJammingClassifier(
        ForceRateJammingConfig(sample_rate_hz=100.0),
        BuildContext(id="jam", rng=np.random.default_rng(0)),
    )
    assert isinstance(classifier, Trainable) and classifier.training_report() == {}
    t = np.arange(400) / 100.0
    force = np.where(t < 2.0, 2.0, 2.0 + 40.0 * (t - 2.0))  # free, then a steep rise
    labels = np.where(t < 2.0, 0, 1)
    batch = SampleBatch(t, {"force_n": np.column_stack([force, np.zeros_like(force)])})
    classifier.fit([batch], [labels])
    report = classifier.training_report()
    assert report["recordings"] == 1 and report["samples"] == 400
    assert report["jamming_force_n"] == classifier.config.jamming_force_n


def test_bundled_plugins_declare_their_capabilities():
    from hapticframe.kinds import FeatureExtractor, GridQueryable, Persistent, Trainable
    from hapticframe_bhm import BayesianHilbertMap
    from hapticframe_jamming import ForceRateJammingClassifier
    from hapticframe_sfrnn import FusionRNNClassifier, LinearSVMClassifier, SFRNNClassifier
    from hapticframe_tactile_features import EMDFeatureExtractor, SparseCodingExtractor

    for cls in (SFRNNClassifier, FusionRNNClassifier, LinearSVMClassifier, SparseCodingExtractor):
        assert issubclass(cls, Trainable) and issubclass(cls, Persistent), cls
    assert issubclass(ForceRateJammingClassifier, Trainable)
    assert not issubclass(EMDFeatureExtractor, Trainable)
    assert not issubclass(FeatureExtractor, Trainable)  # fit alone declares nothing
    assert issubclass(BayesianHilbertMap, GridQueryable)
