"""The learned-zone sensor model (issue 32 §2): its array layer against references, a fit
on synthetic calibration recordings that recovers where the reports come from, the
artifact round trip and its refusals, and ``hapticframe train`` fitting it from a run."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from hapticframe.cli._cli import main
from hapticframe.kinds import BuildContext, CalibrationRecording, LocatedMeasurement
from hapticframe_learned_zone import LearnedZone, LearnedZoneConfig
from hapticframe_learned_zone._functional import (
    inside_outlines,
    likelihood_tables,
    log_ratio,
    observation_weights,
    onset_window,
    travel_thinning,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
ROOT = EXAMPLES.parent
CLASSES = ("free", "jamming", "contact")


def _zone(**config) -> LearnedZone:
    return LearnedZone(LearnedZoneConfig(**config),
                       BuildContext(id="zone", rng=np.random.default_rng(0)))


def _circle(center, radius, n=64):
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t)])


def test_inside_outlines_agrees_with_matplotlib():
    rng = np.random.default_rng(1)
    star = np.array([[0, 0], [2, 0.5], [4, 0], [3, 2], [4, 4], [2, 3], [0, 4], [1, 2]], float)
    points = rng.uniform(-0.5, 4.5, size=(4000, 2))
    ours = inside_outlines(points, [star])
    reference = MplPath(star).contains_points(points)
    # Points on an edge may go either way; away from the edges the two agree exactly.
    assert np.mean(ours == reference) > 0.999
    assert inside_outlines(points.reshape(40, 100, 2), [star]).shape == (40, 100)
    assert not inside_outlines(points, []).any()


def test_thinning_and_the_onset_window():
    x = np.arange(0.0, 0.1, 0.001)
    positions = np.column_stack([x, np.zeros_like(x)])
    movement = np.r_[np.zeros(50, int), np.ones(50, int)]
    keep = travel_thinning(positions, movement, 0.01)
    assert keep[0] and keep[50] and 9 <= keep.sum() <= 12
    labels = np.zeros(100, int)
    labels[20] = 1  # first movement: an onset at 20 mm of its travel
    window = onset_window(positions, movement, labels, 0.005)
    assert window[:26].all() and not window[26:50].any()
    assert window[50:].all()  # the second movement never reported one: all of it counts


def test_a_cell_never_occupied_says_nothing():
    n_occ = np.zeros((1, 2, 3))
    n_free = np.zeros((1, 2, 3))
    n_free[0, :, 0] = 500.0  # free reported 500 times, both cells empty each time
    n_occ[0, 1, 1] = 50.0    # cell 1 held the object 50 times, jamming reported ...
    n_free[0, 0, 1] = 50.0   # ... while cell 0 was empty
    p_occ, p_free, occupied = likelihood_tables(n_occ, n_free, [0.9, 0.09, 0.01], 4.0)
    jam = np.array([0.0, 1.0, 0.0])
    ratio = log_ratio(p_occ[-1], p_free[-1], jam)
    assert abs(ratio[0]) < 0.1  # the prior: no occupied sample, no information
    assert ratio[1] > 3.0
    assert occupied[-1].tolist() == [0.0, 50.0]
    weights = observation_weights(ratio, occupied[-1], 4.0, 2.0)
    assert weights[0] == 0.0 and weights[1] > 0.9  # what was never seen occupied weighs 0


def _approaches(rng, onset_m=0.03, n=24):
    """Straight movements at an 8 cm circle from all sides; the classifier reports
    jamming once the circle's edge is within ``onset_m`` ahead."""
    center, radius = np.array([0.4, 0.25]), 0.04
    rows = {k: [] for k in ("t", "p", "h", "d", "m", "q")}
    t0 = 0.0
    for k in range(n):
        angle = 2 * np.pi * k / n
        offset = rng.uniform(-0.02, 0.02)
        heading = angle + np.pi
        start = center + 0.2 * np.array([np.cos(angle), np.sin(angle)]) \
            + offset * np.array([-np.sin(angle), np.cos(angle)])
        s = np.arange(0.0, 0.2 - radius, 0.002)
        p = start + s[:, None] * np.array([np.cos(heading), np.sin(heading)])
        gap = np.hypot(*(p - center).T) - radius
        label = np.where(gap <= 0.003, 2, np.where(gap <= onset_m, 1, 0))
        rows["t"].append(t0 + s / 0.05)
        t0 += s[-1] / 0.05 + 1.0
        rows["p"].append(p)
        rows["h"].append(np.full(len(s), heading))
        rows["d"].append(np.full(len(s), 0.044))
        rows["m"].append(np.full(len(s), k))
        rows["q"].append(np.eye(3)[label])
    cat = {k: np.concatenate(v) for k, v in rows.items()}
    return CalibrationRecording(cat["t"], cat["p"], cat["h"], cat["d"], cat["m"], cat["q"],
                                CLASSES, [_circle(center, radius)], source="synthetic")


@pytest.mark.parametrize("onset_m", [0.02, 0.04])
def test_fit_recovers_how_far_ahead_jamming_speaks(onset_m):
    zone = _zone()
    zone.fit([_approaches(np.random.default_rng(3), onset_m)])
    reach = zone.training_report()["reach_ahead_m"]["jamming"]
    # The object's near edge lies within onset_m ahead; an 8 cm circle then fills cells
    # up to a diameter beyond it: the odds rise farther ahead for the later onset.
    assert onset_m <= reach <= onset_m + 0.08 + 0.01
    targets, ratio, weights = zone.cell_maps(np.eye(3)[0], 0.044)
    centre = int(np.argmin(np.abs(zone.aside_m)))
    # A free report rules the object out where it would have been jamming's onset.
    at_onset = int(np.argmin(np.abs(zone.ahead_m - onset_m)))
    assert ratio[at_onset, centre] < -2.0 and targets[at_onset, centre] < 0.15
    assert weights[at_onset, centre] > 0.8
    assert int(np.argmin(ratio[:, centre])) == at_onset


def test_fits_of_two_onsets_differ_and_observe_where_the_object_was():
    early, late = _zone(), _zone()
    early.fit([_approaches(np.random.default_rng(3), 0.04)])
    late.fit([_approaches(np.random.default_rng(3), 0.015)])
    assert (early.training_report()["reach_ahead_m"]["jamming"]
            > late.training_report()["reach_ahead_m"]["jamming"])
    report = LocatedMeasurement(np.array([0.0]), np.array([[0.0, 0.0]]), np.array([0.0]),
                                np.array([[0.0, 1.0, 0.0]]), CLASSES, np.array([0.044]))
    obs = early.observe(report)
    occupied = obs.points_m[(obs.targets > 0.8) & (obs.weights > 0.3)]
    assert len(occupied) and np.all(occupied[:, 0] > 0.0)  # the evidence lies ahead (+x)


def test_save_load_round_trip_and_refusals(tmp_path):
    zone = _zone()
    with pytest.raises(ValueError, match="before a fit"):
        zone.save(tmp_path)
    zone.fit([_approaches(np.random.default_rng(5))])
    zone.save(tmp_path)
    loaded = _zone(model_dir=str(tmp_path))
    q = np.array([0.2, 0.7, 0.1])
    for a, b in zip(zone.cell_maps(q, 0.03), loaded.cell_maps(q, 0.03), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=0)
    assert loaded.training_report()["samples_counted"] == \
        zone.training_report()["samples_counted"]
    data = json.loads((tmp_path / "learned_zone.json").read_text())
    data["counts_free"] = data["counts_free"][:-1]
    (tmp_path / "learned_zone.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match="counts must have shape"):
        _zone(model_dir=str(tmp_path))
    with pytest.raises(ValueError, match="not a learned-zone model"):
        _zone(model_dir=str(tmp_path / "missing"))


def test_fit_refusals():
    zone = _zone()
    with pytest.raises(ValueError, match="no calibration recordings"):
        zone.fit([])
    far = _approaches(np.random.default_rng(0))
    away = CalibrationRecording(far.timestamps_s, far.positions_m, far.headings_rad,
                                far.depth_m, far.movement_index, far.probabilities, CLASSES,
                                [_circle((5.0, 5.0), 0.04)])
    with pytest.raises(ValueError, match="no counted sample had the known object"):
        zone.fit([away])


def test_a_classifier_of_other_classes_is_refused():
    zone = _zone()
    report = LocatedMeasurement(np.array([0.0]), np.array([[0.0, 0.0]]), np.array([0.0]),
                                np.array([[0.5, 0.5]]), ("free", "contact"), np.array([0.04]))
    with pytest.raises(ValueError, match="fit it on recordings of this classifier"):
        zone.observe(report)


def test_the_bundled_model_speaks_ahead():
    # the analytic sandbox's jamming is first reported 2.6-3.8 cm before the object: the
    # odds rise from there across an object's size (contact is too rare there to say)
    assert 0.02 <= _zone().reach_ahead_m()["jamming"] <= 0.12


@pytest.mark.slow  # about 4 s: a recorded search and a train
def test_train_fits_the_learned_zone_from_a_recorded_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(EXAMPLES / "search-ellipse-learned-zone.yaml"),
                 "--out", "runs/recorded", "--quiet", "--set", "robots[0].type=sandbox",
                 "--set", "zone.model_dir=null", "--set", "run.halt_on_interaction=false",
                 "--set", "run.max_movements=6", "--set", "run.figures=false",
                 "--set", "run.record=false",
                 "--set", "scene.objects=[{shape: circle, center_m: [0.25, 0.32], "
                 "radius_m: 0.03}]"]) == 0
    assert main(["train", str(EXAMPLES / "calibrate-learned-zone.yaml"), "--out", "runs/lz",
                 "--calibration", "runs/recorded"]) == 0
    record = json.loads(Path("runs/lz/train.json").read_text())
    assert record["trained"] == ["zone"]
    assert record["calibration_runs"] == ["runs/recorded"]
    report = record["reports"]["zone"]
    assert report["classes"] == list(CLASSES) and report["samples_with_object_in_grid"] > 0
    assert "classifier 'jamming'" in report["recordings"][0]
    assert Path("runs/lz/zone/learned_zone.json").is_file()
    # the search loads it
    assert main(["run", str(EXAMPLES / "search-ellipse-learned-zone.yaml"), "--out",
                 "runs/search", "--quiet", "--set", "robots[0].type=sandbox",
                 "--set", "zone.model_dir=runs/lz/zone", "--set", "run.max_movements=2",
                 "--set", "run.figures=false", "--set", "run.record=false"]) == 0


def test_train_refuses_calibration_runs_nothing_learns_from(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["train", str(EXAMPLES / "search-ellipse-distance.yaml"), "--out", "out",
                 "--calibration", "runs/none", "--set", "estimator.model_dir=null",
                 "--set", "estimator.pretrained=true"])
    assert code == 2
    assert "no sensor model of the experiment learns from calibration" in capsys.readouterr().err


@pytest.mark.slow  # about 3 s: a recorded search and a train
def test_train_fits_the_failure_zone_kernel_too(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # halt off: the sandbox's movements run into the object's 80 N force limit, which
    # makes the run "no result" (exit 1) while its recording is complete
    assert main(["run", str(EXAMPLES / "search-ellipse.yaml"), "--out", "rec", "--quiet",
                 "--set", "run.halt_on_interaction=false", "--set", "run.max_movements=6",
                 "--set", "run.figures=false", "--set", "run.record=false"]) in (0, 1)
    assert main(["train", str(EXAMPLES / "search-ellipse.yaml"), "--out", "fz",
                 "--calibration", "rec"]) == 0
    record = json.loads(Path("fz/train.json").read_text())
    assert record["trained"] == ["failure-zone"]
    assert Path("fz/failure-zone/failure_zone_fit.json").is_file()


def test_train_names_a_run_that_is_no_calibration_recording(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["train", str(EXAMPLES / "calibrate-learned-zone.yaml"), "--out", "out",
                 "--calibration", str(tmp_path)])
    assert code == 2
    assert "run.calibration_runs[0]" in capsys.readouterr().err


def test_a_report_is_its_most_probable_class_unless_soft():
    zone, soft = _zone(), _zone(mixture="soft")
    rec = _approaches(np.random.default_rng(3), 0.03)
    zone.fit([rec])
    soft.fit([rec])
    report = LocatedMeasurement(np.array([0.0]), np.array([[0.0, 0.0]]), np.array([0.0]),
                                np.array([[0.4, 0.6, 0.0]]), CLASSES, np.array([0.044]))
    hard = LocatedMeasurement(np.array([0.0]), np.array([[0.0, 0.0]]), np.array([0.0]),
                              np.array([[0.0, 1.0, 0.0]]), CLASSES, np.array([0.044]))
    a, b = zone.observe(report), _zone_fitted_like(zone).observe(hard)
    np.testing.assert_array_equal(a.targets, b.targets)
    # as a mixture, 0.4 of "free" pulls the same report's targets towards 1/2
    assert soft.observe(report).targets.max() < a.targets.max()


def _zone_fitted_like(zone: LearnedZone) -> LearnedZone:
    fresh = _zone()
    fresh._use(zone._model)
    return fresh


@pytest.mark.slow  # about 10 s: the example's commands in mpm-sand
def test_the_calibrated_example_finds_its_ellipse_in_mpm_sand(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the examples' paths are relative to where they run
    search = str(EXAMPLES / "search-ellipse-learned-zone.yaml")
    for run_dir, centre in (("calibration-physics", "[0.25, 0.32]"),
                            ("calibration-physics-2", "[0.55, 0.16]")):
        assert main(["run", search, "--out", f"runs/{run_dir}", "--quiet",
                     "--set", "zone.model_dir=null", "--set", "run.halt_on_interaction=false",
                     "--set", "run.max_movements=12", "--set", "run.figures=false",
                     "--set", f"scene.objects=[{{shape: circle, center_m: {centre}, "
                     "radius_m: 0.04}]"]) == 0
    assert main(["train", str(EXAMPLES / "calibrate-learned-zone.yaml"),
                 "--out", "runs/learned-zone"]) == 0
    assert main(["run", search, "--out", "runs/search", "--quiet",
                 "--set", "run.figures=false"]) == 0
    metrics = json.loads(Path("runs/search/metrics.json").read_text())
    # Found (within the evaluation's 4 cm); how well is the README's to say (below): in the
    # engine's second library the calibrated outline is coarse (docs/benchmarks.md).
    assert metrics["object_found"] and metrics["centroid_error_m"] < 0.04 + 1e-3
    # The README states this run's outcome as it is.
    stated = re.search(r"It finds the ellipse in (\d+) movements, centroid error ([\d.]+) cm",
                       (ROOT / "README.md").read_text())
    assert stated is not None, "the README no longer states the calibrated example's outcome"
    assert int(stated.group(1)) == metrics["movements"]
    assert float(stated.group(2)) == pytest.approx(100 * metrics["centroid_error_m"], abs=0.05)
