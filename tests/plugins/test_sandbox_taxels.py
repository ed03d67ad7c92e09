"""The sandbox's taxel measurement model (``sandbox-taxels``), its fit to the real trials,
and the search with the distance estimate (issue 27 §4)."""

from __future__ import annotations

import numpy as np
import pytest

import hapticframe
from hapticframe import Circle, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement, SampleBatch, concatenate_batches
from hapticframe_raking import RakingEstimator, RakingEstimatorConfig, load_trials
from hapticframe_raking._sandbox_calibration import calibrate_sandbox_taxels
from hapticframe_sandbox import (
    SandboxRobot,
    SandboxRobotConfig,
    SandboxTaxelSensor,
    SandboxTaxelSensorConfig,
    TaxelModel,
    fit_taxel_model,
    force_components,
    raking_labels,
)

CIRCLE = Circle(center_m=(0.3, 0.25), radius_m=0.04)


def _robot_and_sensor(**config: object) -> tuple[SandboxRobot, SandboxTaxelSensor]:
    scene = Scene(objects=[CIRCLE])
    robot = SandboxRobot(SandboxRobotConfig(), BuildContext("arm", np.random.default_rng(1),
                                                            scene=scene))
    sensor = SandboxTaxelSensor(SandboxTaxelSensorConfig(**config),  # type: ignore[arg-type]
                                BuildContext("taxels", np.random.default_rng(2),
                                             inputs={"arm": robot}, scene=scene))
    return robot, sensor


def test_force_components_split_along_and_across_the_heading() -> None:
    # Heading +x: a force towards -x resists the motion; +y lies to its left.
    along, across = force_components(np.array([[-3.0, 2.0]]), np.array([0.0]))
    np.testing.assert_allclose([along[0], across[0]], [3.0, 2.0])
    along, across = force_components(np.array([[0.0, -5.0]]), np.array([np.pi / 2]))
    np.testing.assert_allclose([along[0], across[0]], [5.0, 0.0], atol=1e-12)


def test_labels_measure_to_the_nearest_outline_point() -> None:
    outline = np.asarray(CIRCLE.outline(720))
    p = np.array([[0.16, 0.25], [0.16, 0.25], [0.3, 0.1]])
    heading = np.array([0.0, np.pi / 2, np.pi / 2])
    distance, direction, depth = raking_labels(p, heading, np.array([0.044, 0.02, 0.044]),
                                               [outline], direction_split_deg=10.0,
                                               deep_m=0.03)
    np.testing.assert_allclose(distance, [100.0, 100.0, 110.0], atol=0.05)
    # Straight ahead, then 90 degrees clockwise of a heading of +y, then ahead again.
    np.testing.assert_array_equal(direction, [1.0, 0.0, 1.0])
    np.testing.assert_array_equal(depth, [0.0, 1.0, 0.0])
    empty = raking_labels(p, heading, np.zeros(3), [], direction_split_deg=10.0, deep_m=0.03)
    assert np.all(np.isnan(empty[0]))


def test_fit_recovers_a_known_linear_model() -> None:
    rng = np.random.default_rng(0)
    n = 6000
    distance = rng.uniform(0, 200, n)
    direction = rng.integers(0, 3, n)
    along = 15 + 30 * np.exp(-distance / 20) + rng.normal(0, 0.5, n)
    across = (direction - 1) * 4 * np.exp(-distance / 30) + rng.normal(0, 0.5, n)
    truth = TaxelModel(rng.uniform(0, 1, (4, 3)), rng.uniform(-0.02, 0.02, (4, 3)),
                       rng.uniform(-0.02, 0.02, (4, 3)), np.full((4, 3), 0.03))
    real = truth.apply(along, across, rng)
    fitted = fit_taxel_model(real, distance, direction, along, across, distance, direction)
    np.testing.assert_allclose(fitted.gain_along_per_n, truth.gain_along_per_n, atol=2e-3)
    np.testing.assert_allclose(fitted.gain_across_per_n, truth.gain_across_per_n, atol=3e-3)
    np.testing.assert_allclose(fitted.offset, truth.offset, atol=0.05)
    np.testing.assert_allclose(fitted.noise_std, 0.03, atol=0.01)
    with pytest.raises(ValueError, match="cells"):
        fit_taxel_model(real[:30], distance[:30], direction[:30], along[:30], across[:30],
                        distance[:30], direction[:30])
    bad = real.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_taxel_model(bad, distance, direction, along, across, distance, direction)


def test_the_shipped_numbers_are_the_calibration() -> None:
    fitted = calibrate_sandbox_taxels()
    default = SandboxTaxelSensorConfig()
    for field in ("offset", "gain_along_per_n", "gain_across_per_n", "noise_std"):
        np.testing.assert_allclose(getattr(default, field), fitted[field], atol=1e-4)
    assert fitted["real_samples"] == 10043 and fitted["sandbox_samples"] > 10_000


def test_live_readings_follow_the_declared_model() -> None:
    robot, sensor = _robot_and_sensor(noise_std=(0.0,) * 12)
    robot.begin(ExploratoryMovement(np.array([0.1, 0.25]), np.array([0.24, 0.25]),
                                     speed_m_per_s=0.05))
    batches = []
    while robot.step() is not None:
        batches.append(sensor.read())
    batch = concatenate_batches(batches)
    truth = robot.ground_truth
    along, across = force_components(truth.forces_n, np.zeros(len(truth)))
    model = TaxelModel.from_config(sensor.config)
    expected = model.offset + model.gain_along_per_n * along[:, None, None] + (
        model.gain_across_per_n * across[:, None, None])
    np.testing.assert_allclose(batch.channels["taxel_force"], expected, atol=1e-12)
    d = batch.channels["distance_mm"]
    assert d[0] == pytest.approx(159.5, abs=0.2)  # after one 0.5 mm step and np.all(np.diff(d) < 0)
    assert set(np.unique(batch.channels["direction_class"])) == {1.0}
    # A rewound sensor reads the same steps with the same noise again.
    arm, noisy = _robot_and_sensor()
    arm.begin(ExploratoryMovement(np.array([0.1, 0.25]), np.array([0.2, 0.25])))
    mark = noisy.checkpoint()
    arm.step()
    first = noisy.read()
    noisy.rewind(mark)
    np.testing.assert_array_equal(noisy.read().channels["taxel_force"],
                                  first.channels["taxel_force"])
    with pytest.raises(ValueError, match="sandbox"):
        SandboxTaxelSensor(SandboxTaxelSensorConfig(), BuildContext(
            "t", np.random.default_rng(0), inputs={}))


def test_approach_trials_make_a_finite_training_source() -> None:
    _, sensor = _robot_and_sensor(approach_trials=2, approach_standoff_m=0.05)
    recordings = list(sensor.iter_recordings())
    assert len(recordings) == 2 and sensor.exhausted
    for rec in recordings:
        assert rec.channels["taxel_force"].shape == (len(rec), 4, 3)
        assert np.nanmin(rec.channels["distance_mm"]) < 5.0  # each approach reaches it
    with pytest.raises(RuntimeError, match="training source"):
        sensor.read()


def test_a_movement_end_starts_a_new_window() -> None:
    a, b = load_trials("testing")[:2]
    est = RakingEstimator(RakingEstimatorConfig(pretrained=True),
                          BuildContext("est", np.random.default_rng(0)))
    est.update(SampleBatch(np.arange(len(a)) / 10.0, {"taxel_force": a.force}))
    est.on_movement_end(None)  # type: ignore[arg-type]
    t0 = 0.1 * len(a)  # no pause: only the movement's end separates them
    est.update(SampleBatch(t0 + np.arange(len(b)) / 10.0, {"taxel_force": b.force}))
    fresh = RakingEstimator(RakingEstimatorConfig(pretrained=True),
                            BuildContext("est", np.random.default_rng(0)))
    fresh.update(SampleBatch(np.arange(len(b)) / 10.0, {"taxel_force": b.force}))
    np.testing.assert_allclose(est.estimates[1].distance_mm[len(a):],
                               fresh.estimates[1].distance_mm, atol=1e-9)


@pytest.mark.parametrize("path", ["examples/search-ellipse-distance.yaml",
                                  "examples/search-ellipse-raking-train.yaml"])
def test_the_examples_validate(path: str) -> None:
    assert hapticframe.validate_file(path).seed == 7


def test_the_bench_swaps_in_the_distance_chain() -> None:
    from hapticframe_bench._search_distance import distance_experiment
    from hapticframe_bench._template import search_experiment

    data = search_experiment([{"shape": "circle", "center_m": [0.3, 0.2], "radius_m": 0.04}],
                             "two-phase-coverage", 3, "t")
    changed = distance_experiment(data, "runs/x")
    experiment = hapticframe.validate_mapping(changed)
    assert [s["type"] for s in changed["sensors"]] == ["sandbox-taxels"]
    assert all(m["inputs"] == ["distance"] for m in changed["maps"])
    assert experiment.seed == 3 and data["sensors"][0]["type"] == "sandbox-force"
    # The estimator's classes are far / near: "far" is free movement for the planner.
    assert [p["config"]["free_class_names"] for p in changed["planners"]] == [["far"]]
    assert "config" not in data["planners"][0] or (
        "free_class_names" not in data["planners"][0]["config"])
