"""The force observer calibrated from the CLI, as a lab does on its rig (issue 14, section 7).

The three commands of examples/calibrate-force-observer.yaml, run in a scratch directory
exactly as written there: record free motions in air through the emulated FT 300 and
BNO055 (examples/free-motion-ft300.yaml), fit the observer with ``hapticframe train``
(examples/calibrate-force-observer.yaml, which reads ``runs/free-motion`` and trains no
classifier, so needs no labels), and run the chapter 3 search (a copy of
examples/search-ellipse-ft300.yaml whose observer loads ``model_dir`` in place of the
inline parameters of the emulated rig).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from hapticframe.cli._cli import main

pytestmark = pytest.mark.slow  # 8-10 s: two runs through pty emulators and a fit

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
MODEL_DIR = "runs/observer/observer"

#: The emulated rig of the examples: m_e of the sandbox, R = the IMU's mount R_z(90°) (the
#: rotation sensor ← IMU), ε = the FT 300's offset.
TRUE_MASS_KG = 0.8
TRUE_ROTATION = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
TRUE_BIAS_N = np.array([1.5, -0.8, 2.0])


def _calibrated_search(source: Path) -> dict[str, Any]:
    """search-ellipse-ft300.yaml with the observer loading the fitted model."""
    data = yaml.safe_load(source.read_text())
    (observer,) = [e for e in data["feature_extractors"] if e["id"] == "observer"]
    config = observer["config"]
    for inline in ("mass_kg", "imu_rotation_wxyz", "bias_n"):
        assert inline in config  # the example describes the emulated rig inline ...
        del config[inline]
    config["model_dir"] = MODEL_DIR  # ... which the fitted model replaces
    data["run"] = {**data.get("run", {}), "figures": False}
    return data


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scratch directory after the three commands of calibrate-force-observer.yaml."""
    root = tmp_path_factory.mktemp("lab")
    search = root / "search-ellipse-ft300-calibrated.yaml"
    search.write_text(yaml.safe_dump(_calibrated_search(EXAMPLES / "search-ellipse-ft300.yaml"),
                                     sort_keys=False))
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(root)  # the examples' paths are relative to where hapticframe runs
        assert main(["run", str(EXAMPLES / "free-motion-ft300.yaml"),
                     "--out", "runs/free-motion", "--quiet"]) == 0
        assert main(["train", str(EXAMPLES / "calibrate-force-observer.yaml"),
                     "--out", "runs/observer"]) == 0
        assert main(["run", search.name, "--out", "runs/search", "--quiet"]) == 0
    return root


def _report(lab: Path) -> dict[str, Any]:
    record = json.loads((lab / "runs/observer/train.json").read_text())
    report: dict[str, Any] = record["reports"]["observer"]
    return report


def test_the_free_motion_run_records_both_devices_in_air(lab):
    run = lab / "runs/free-motion"
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["max_force_n"] == 0.0  # no environment force: drag, jamming, contact off
    assert metrics["movements"] >= 4
    with np.load(run / "trace.npz") as trace:
        force = trace["sensor/wrist/force_n"]
        accel = trace["sensor/imu/acceleration_m_per_s2"]
        movements = np.unique(trace["robot/arm/movement_index"])
        headings = np.unique(np.round(trace["robot/arm/heading_rad"], 3))
    assert force.shape[1:] == accel.shape[1:] == (3,) and len(force) > 300
    assert len(accel) > 300
    assert len(headings) >= 2  # raked back and forth
    # What the FT 300 read is gravity, inertia and offset only: about m_e g + ε.
    expected = np.linalg.norm(TRUE_MASS_KG * 9.80665 * np.array([0, 0, 1.0]) + TRUE_BIAS_N)
    assert np.median(np.linalg.norm(force, axis=1)) == pytest.approx(expected, rel=0.05)
    assert len(movements) == metrics["movements"]


def test_train_fits_the_observer_without_labels(lab):
    record = json.loads((lab / "runs/observer/train.json").read_text())
    assert record["trained"] == ["observer"]
    assert record["artifacts"] == {"observer": str(Path("runs/observer/observer"))}
    assert (lab / MODEL_DIR / "model.json").is_file()
    assert (lab / MODEL_DIR / "model.npz").is_file()
    with np.load(lab / "runs/free-motion/trace.npz") as trace:
        movements = len(np.unique(trace["robot/arm/movement_index"]))
        wrist_samples = len(trace["sensor/wrist/timestamps_s"])
    assert record["recordings"] == movements  # one per movement, both sensors split alike
    report = _report(lab)
    # The IMU was held onto the FT 300's timestamps: (nearly) every force sample is used,
    # those before the IMU's first sample being invalid.
    assert 0.95 * wrist_samples <= report["samples"] <= wrist_samples


def test_the_fit_recovers_the_emulated_rig(lab):
    report = _report(lab)
    assert report["mass_kg"] == pytest.approx(TRUE_MASS_KG, rel=0.03)
    rotation = np.asarray(report["rotation"])
    error = rotation.T @ TRUE_ROTATION
    angle_deg = math.degrees(math.acos(np.clip((np.trace(error) - 1) / 2, -1, 1)))
    assert angle_deg < 3.0
    assert np.linalg.norm(np.asarray(report["bias_n"]) - TRUE_BIAS_N) < 0.3
    # Gravity, inertia and offset (about 10 N) are removed down to the sensors' noise.
    assert report["residual_rms_before_n"] > 8.0
    assert report["residual_rms_n"] < 0.03 * report["residual_rms_before_n"]
    # The sandbox only yaws: one direction excited, and the fit says so.
    assert report["excited_directions"] == 1 and "not identifiable" in report["warning"]


def test_the_saved_model_is_what_train_reported(lab):
    meta = json.loads((lab / MODEL_DIR / "model.json").read_text())
    report = _report(lab)
    assert meta["mass_kg"] == report["mass_kg"]
    assert meta["bias_n"] == pytest.approx(report["bias_n"], abs=1e-12)
    with np.load(lab / MODEL_DIR / "model.npz", allow_pickle=False) as arrays:
        assert np.allclose(arrays["rotation"], report["rotation"], atol=1e-12)


def test_the_search_with_the_fitted_observer_finds_the_object(lab):
    run = lab / "runs/search"
    resolved = json.loads((run / "run.json").read_text())
    assert MODEL_DIR in json.dumps(resolved)  # the run loaded the fitted model
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["object_found"] is True
    assert metrics["centroid_error_m"] <= 0.02  # issue 14: at most 2 cm, as with the truth
