"""The perception example: fit on synthetic trials, then stream one trial into a belief map."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe import get_registry
from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "perception-belief-map.yaml"
FROM_TRAINED = ROOT / "examples" / "perception-from-trained.yaml"

pytest.importorskip("torch")
pytest.importorskip("sklearn")

# The example's components as shipped, shrunk so that fitting takes seconds: four training
# trials, one pass of dictionary learning, small dictionaries and a small network. Three epochs
# at a higher learning rate still teach the network to call contact (it did, at a balanced
# accuracy of 0.88, on the seed of the example), so the contact snapshots must appear.
SMALL_CODES = "pac_atoms: 16, pdc_atoms: 8, electrodes_atoms: 8, fit_epochs: 1"
SMALL_NETWORK = (
    "max_epochs: 3, learning_rate: 0.01, pac_code_size: 16, pdc_code_size: 8, "
    "electrodes_code_size: 8, gru_layers: 1, gru_units: 8, fusion_units: 16"
)
SMALL_TRIALS = 4


def _fit_in_run_text() -> str:
    text = EXAMPLE.read_text()
    assert "n_trials: 40" in text and "max_epochs: 8, amplitude_inputs: true" in text
    assert "config: {amplitude: channel}" in text
    text = text.replace("n_trials: 40", f"n_trials: {SMALL_TRIALS}")
    text = text.replace("config: {amplitude: channel}",
                        f"config: {{amplitude: channel, {SMALL_CODES}}}")
    text = text.replace("max_epochs: 8, amplitude_inputs: true",
                        f"amplitude_inputs: true, {SMALL_NETWORK}")
    return text.replace("../schemas/", str(ROOT / "schemas") + "/")


def _from_trained_text(artifacts: Path) -> str:
    """The shipped examples/perception-from-trained.yaml with the example's components shrunk
    as above and its artifact paths pointed at `artifacts` (it names runs/trained)."""
    text = FROM_TRAINED.read_text()
    codes = "config: {amplitude: channel, dictionary_file: runs/trained/codes}"
    network = "config: {amplitude_inputs: true, model_dir: runs/trained/sf-rnn}"
    assert codes in text and network in text
    text = text.replace(codes, f"config: {{amplitude: channel, {SMALL_CODES}, "
                               f"dictionary_file: '{artifacts / 'codes'}'}}")
    text = text.replace(network, f"config: {{amplitude_inputs: true, {SMALL_NETWORK}, "
                                 f"model_dir: '{artifacts / 'sf-rnn'}'}}")
    return text.replace("../schemas/", str(ROOT / "schemas") + "/")


def _must_not_fit(*args: object, **kwargs: object) -> None:
    raise AssertionError("a component was fitted in a run that loads its artifacts")


@pytest.fixture(scope="module")
def experiment(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shrunk example, fitting before the run (`run.train_from`)."""
    path = tmp_path_factory.mktemp("perception") / "fit-in-run.yaml"
    path.write_text(_fit_in_run_text())
    return path


@pytest.fixture(scope="module")
def fit_run(experiment: Path) -> tuple[Path, str]:
    """Output folder and printed text of `hapticframe run` on the experiment, once per module;
    the tests only read what it wrote."""
    out = experiment.parent / "fit"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["run", str(experiment), "--out", str(out)]) == 0
    return out, printed.getvalue()


@pytest.fixture(scope="module")
def artifacts_run(experiment: Path) -> tuple[Path, Path]:
    """`hapticframe train` on the experiment, then the shipped perception-from-trained.yaml,
    which loads its artifacts instead of fitting: the artifacts folder and the run's output."""
    artifacts = experiment.parent / "artifacts"
    assert main(["train", str(experiment), "--out", str(artifacts)]) == 0
    from_trained = experiment.parent / "from-trained.yaml"
    from_trained.write_text(_from_trained_text(artifacts))
    out = experiment.parent / "files"
    registry = get_registry()
    with pytest.MonkeyPatch.context() as patch:  # a run that loads must fit nothing
        for kind, name in (("feature_extractor", "sparse-coding"), ("classifier", "sf-rnn")):
            patch.setattr(registry.get(kind, name).spec.load_factory(), "fit", _must_not_fit)
        assert main(["run", str(from_trained), "--out", str(out), "--quiet"]) == 0
    return artifacts, out


def test_the_example_trains_first_and_writes_the_timeline_and_snapshots(fit_run):
    out, printed = fit_run
    assert f"fitting before the run on {SMALL_TRIALS} recordings of training-trials" in printed

    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "ok"
    assert record["details"]["training"]["trained"] == ["emd", "codes", "sf-rnn"]
    metrics = json.loads((out / "metrics.json").read_text())
    # The trained network calls contact on part of the trial, so there is contact to show.
    assert 0.0 < metrics["contact_fraction"] < 1.0
    # The core scores the SF-RNN against the streamed trial's contact labels (Figure 2.5).
    assert metrics["contact_labels_from"] == "fingertip" and metrics["contact_frames"] > 200
    assert 0.0 <= metrics["contact_balanced_accuracy"] <= 1.0
    # The scene's cylinder: with no planner the core scores the last map against it.
    assert metrics["evaluated_map"] == "belief" and metrics["object_found"]
    assert metrics["centroid_error_m"] < 0.03
    names = {p.name for p in out.glob("*.png")}
    assert {"labels.png", "timeline.png", "belief_first_contact.png", "belief_mid_contact.png",
            "belief_last_contact.png", "belief_final.png", "outline.png"} <= names
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        assert not any(key.startswith("sensor/training-trials/") for key in trace.files)
        frames = len(trace["sensor/fingertip/timestamps_s"])
        probabilities = trace["classifier/sf-rnn/probabilities"]
    assert frames > 200  # one trial of about 3 s at 100 frames/s
    assert probabilities.shape[1] == 2 and np.all(np.isfinite(probabilities))
    assert np.allclose(probabilities.sum(axis=1), 1.0)


def test_saved_artifacts_reproduce_the_run_time_fit(fit_run, artifacts_run):
    # A run that loads the artifacts of `hapticframe train` must classify every frame exactly
    # as the run that fitted the same components before streaming.
    artifacts, files_run = artifacts_run
    assert (artifacts / "codes" / "dictionaries.npz").is_file()
    assert (artifacts / "sf-rnn" / "weights.pt").is_file()
    probabilities = {}
    for name, out in (("fit", fit_run[0]), ("files", files_run)):
        record = json.loads((out / "run.json").read_text())
        assert record["status"] == "ok"
        assert ("training" in record["details"]) == (name == "fit")
        with np.load(out / "trace.npz", allow_pickle=False) as trace:
            probabilities[name] = trace["classifier/sf-rnn/probabilities"]
    assert probabilities["fit"].shape == probabilities["files"].shape
    assert len(probabilities["fit"]) > 200
    # Not a constant output, which any two untrained-alike networks would share.
    assert np.ptp(probabilities["fit"][:, 1]) > 0.1
    np.testing.assert_allclose(probabilities["files"], probabilities["fit"], rtol=0, atol=1e-6)


def test_both_examples_place_the_streamed_trials_cylinder(fit_run):
    # The scene is the truth the belief maps draw and are scored against: the same in both
    # examples, a 9.1 cm footprint (the cylinder's diameter across the rake, the sensor's
    # contact interval at the depth of its axis) holding every labelled contact position,
    # in a region that holds the whole rake.
    import yaml

    from hapticframe import Scene
    from hapticframe_biotac import TrialSpec, contact_interval_x_m

    scenes = [yaml.safe_load(p.read_text())["scene"] for p in (EXAMPLE, FROM_TRAINED)]
    assert scenes[0] == scenes[1]
    scene = Scene.model_validate(scenes[0])
    (footprint,) = scene.objects
    spec = TrialSpec(medium="cottonwood_beads", speed_m_per_s=0.04, orientation_deg=0.0,
                     object_offset_m=0.0, has_object=True)
    axis_depth_m = 0.04 + 0.091 / 2  # the top 4 cm deep, plus the radius
    across = contact_interval_x_m(spec, depth_m=axis_depth_m)
    assert across is not None
    outline = footprint.outline(400)
    np.testing.assert_allclose([outline[:, 0].min(), outline[:, 0].max()], across, atol=1e-9)
    with np.load(fit_run[0] / "trace.npz", allow_pickle=False) as trace:
        positions = trace["sensor/fingertip/position_m"]
        contact = trace["sensor/fingertip/contact"] > 0.5
    assert contact.sum() > 100
    assert scene.occupied(positions[contact]).all()
    region = scene.region
    assert region.x_min_m < positions[:, 0].min() and positions[:, 0].max() < region.x_max_m
    assert region.y_min_m < positions[:, 1].min() and positions[:, 1].max() < region.y_max_m
