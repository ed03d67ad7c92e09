"""The ``bayesian-hilbert-map`` component (hapticframe_bhm._map) and its registration."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import MapSpec, RegionConfig, Scene
from hapticframe.kinds import BuildContext, Map, Observations, Region, RunOutcome
from hapticframe_bench import labelled_points, roc_auc, two_object_scene
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_bhm import plugin as bhm_plugin
from hapticframe_bhm._config import length_scale_from_bandwidth_per_cm2

#: Table 3.1's map: 2.24 / 3.54 cm length scales switched per region, a zero-mean prior of
#: variance 10 and the Monte-Carlo std of Eq. 3.8 (the defaults are calibrated, see _map).
THESIS = {
    "length_scale_free_m": float(np.sqrt(1 / (2 * 0.1)) / 100),
    "region_dependent_smoothing": True,
    "prior_variance": 10.0,
    "prior_occupancy": 0.5,
    "std_method": "monte_carlo",
    "max_iterations_update": 3,
}


def build(seed: int = 0, scene: Scene | None = None, **config) -> BayesianHilbertMap:
    context = BuildContext(id="bhm", rng=np.random.default_rng(seed), scene=scene)
    return BayesianHilbertMap(BayesianHilbertMapConfig(**config), context)


@pytest.fixture(scope="module")
def scene() -> Scene:
    return two_object_scene()


@pytest.fixture(scope="module")
def data(scene):
    rng = np.random.default_rng(0)
    return labelled_points(scene, 3000, rng), labelled_points(scene, 20_000, rng, 0.0)


# --- construction and configuration ------------------------------------------------------------


def test_region_comes_from_config_then_scene_then_default() -> None:
    assert build().region == Region(0.0, 0.75, 0.0, 0.5)
    scene = Scene(region=RegionConfig(x_min_m=-0.2, x_max_m=0.3, y_min_m=0.0, y_max_m=0.4))
    assert build(scene=scene).region == Region(-0.2, 0.3, 0.0, 0.4)
    own = RegionConfig(x_min_m=0.0, x_max_m=0.2, y_min_m=0.0, y_max_m=0.1)
    assert build(scene=scene, region=own).region == Region(0.0, 0.2, 0.0, 0.1)
    xs, ys = build().hinge_axes
    assert (xs.size, ys.size) == (18, 13)
    assert build().belief.dimension == 18 * 13 + 1
    assert build(bias=False).belief.dimension == 18 * 13


def test_config_validation() -> None:
    config = BayesianHilbertMapConfig()
    assert config.length_scale_free_m == pytest.approx(0.033)
    assert config.length_scale_interaction_m == pytest.approx(np.sqrt(1 / (2 * 0.04)) / 100)
    thesis = BayesianHilbertMapConfig(**THESIS)
    assert thesis.length_scale_free_m == pytest.approx(length_scale_from_bandwidth_per_cm2(0.1))
    for bad in (
        {"hinge_spacing_m": 0.0},
        {"hinge_spacing_m": float("inf")},
        {"prior_variance": -1.0},
        {"length_scale_free_m": float("nan")},
        {"monte_carlo_samples": 1},
        {"std_method": "bootstrap"},
        {"max_iterations_first": 0},
        {"prior_occupancy": 0.0},
        {"prior_occupancy": 1.0},
        {"unknown_key": 1},
    ):
        with pytest.raises(ValidationError):
            BayesianHilbertMapConfig(**bad)
    fields = BayesianHilbertMapConfig.model_json_schema()["properties"]
    assert all(spec.get("description") for spec in fields.values())


def test_too_many_hinges_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="hinge_spacing_m"):
        build(hinge_spacing_m=0.005)


def test_registration_is_import_light_and_resolves() -> None:
    specs = list(bhm_plugin.hapticframe_maps())
    assert len(specs) == 1 and isinstance(specs[0], MapSpec)
    spec = specs[0]
    assert spec.name == "bayesian-hilbert-map"
    assert spec.load_factory() is BayesianHilbertMap
    assert issubclass(BayesianHilbertMap, Map)
    code = (
        "import sys, hapticframe_bhm.plugin; "
        "print(sorted(m for m in ('scipy', 'matplotlib', 'hapticframe_bhm._map') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# --- before data, odd queries -----------------------------------------------------------------


@pytest.mark.parametrize("method", ["monte_carlo", "surrogate"])
def test_prior_map_is_uninformed(method) -> None:
    bhm = build(std_method=method, prior_occupancy=0.5)
    estimate = bhm.query([[0.1, 0.1], [0.5, 0.3], [5.0, -3.0]])
    np.testing.assert_allclose(estimate.mean, 0.5)
    assert np.all(np.isfinite(estimate.std)) and np.all(estimate.std > 0)
    np.testing.assert_allclose(bhm.log_odds([[0.1, 0.1]]), 0.0)


def test_prior_occupancy_sets_the_map_where_no_data_reaches() -> None:
    from hapticframe_bhm import _functional as fn

    bhm = build(prior_occupancy=0.05, prior_variance=0.45)
    assert bhm.belief.mean[-1] == pytest.approx(np.log(0.05 / 0.95))
    np.testing.assert_allclose(bhm.belief.mean[:-1], 0.0)
    # Far outside every hinge only the bias speaks: sigma(kappa logit(0.05)).
    far = bhm.query([[5.0, -3.0]]).mean[0]
    assert far == pytest.approx(fn.probit_probability(np.log(0.05 / 0.95), 0.45))
    near = bhm.query([[0.3, 0.2]]).mean[0]
    assert 0.0 < near < 0.5


def test_queries_accept_empty_float32_single_and_outside_points(data) -> None:
    train, _ = data
    bhm = build()
    bhm.fit(train)
    empty = bhm.query(np.empty((0, 2)))
    assert empty.mean.shape == (0,) and empty.std.shape == (0,)
    assert bhm.query([]).mean.shape == (0,)
    assert bhm.log_odds(np.empty((0, 2))).shape == (0,)
    points = np.array([[0.25, 0.25], [0.1, 0.4]])
    as32 = bhm.query(points.astype(np.float32))
    as64 = bhm.query(points.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(as32.mean, as64.mean)
    single = bhm.query(np.array([0.25, 0.25]))
    assert single.mean.shape == (1,)
    far = bhm.query([[-5.0, 2.0], [100.0, 100.0]])
    assert np.all(np.isfinite(far.mean)) and np.all(np.isfinite(far.std))
    assert np.all((far.mean >= 0) & (far.mean <= 1))
    with pytest.raises(ValueError):
        bhm.query([[np.nan, 0.1]])
    with pytest.raises(ValueError):
        bhm.query(np.zeros((4, 3)))


def test_observations_reject_nan_before_the_map_sees_them() -> None:
    with pytest.raises(ValueError):
        Observations(np.array([[0.1, np.nan]]), np.array([1.0]))
    with pytest.raises(ValueError):
        Observations(np.array([[0.1, 0.1]]), np.array([np.nan]))
    bhm = build()
    with pytest.raises(TypeError):
        bhm.update((np.zeros((1, 2)), np.zeros(1)))  # type: ignore[arg-type]
    bhm.update(Observations.empty())
    assert bhm.batches_fused == 0


# --- accuracy and behaviour -------------------------------------------------------------------


@pytest.mark.parametrize("smoothing", [False, True])
def test_auc_on_the_two_object_scene(data, smoothing) -> None:
    train, test = data
    bhm = build(region_dependent_smoothing=smoothing)
    bhm.fit(train)
    estimate = bhm.query(test.points_m)
    assert roc_auc(test.targets > 0.5, estimate.mean) >= 0.99
    accuracy = np.mean((estimate.mean > 0.5) == (test.targets > 0.5))
    assert accuracy >= 0.98
    assert np.all((estimate.mean >= 0) & (estimate.mean <= 1))


def test_std_falls_near_data(data) -> None:
    train, test = data
    left = train.points_m[:, 0] < 0.35
    observed = test.points_m[:, 0] < 0.3
    unobserved = test.points_m[:, 0] > 0.45
    for config, ratio in ((THESIS, 0.25), ({}, 0.5)):
        bhm = build(**config)
        bhm.fit(Observations(train.points_m[left], train.targets[left]))
        std = bhm.query(test.points_m).std
        assert np.median(std[observed]) < ratio * np.median(std[unobserved]), config


def test_sequential_updates_approximate_one_batch_fit(data) -> None:
    train, test = data
    batch = build(region_dependent_smoothing=False)
    batch.fit(train)
    streamed = build(region_dependent_smoothing=False)
    for rows in np.array_split(np.arange(len(train)), 15):
        part = Observations(train.points_m[rows], train.targets[rows], train.weights[rows])
        streamed.update(part)
    assert streamed.batches_fused == 15
    difference = np.abs(batch.query(test.points_m).mean - streamed.query(test.points_m).mean)
    assert difference.mean() < 0.03
    assert np.quantile(difference, 0.99) < 0.15


def test_fit_forgets_earlier_data(data) -> None:
    train, _test = data
    once = build()
    once.fit(train)
    twice = build()
    twice.update(Observations(train.points_m[:500], 1.0 - train.targets[:500]))
    twice.fit(train)
    np.testing.assert_allclose(twice.belief.mean, once.belief.mean, rtol=1e-10, atol=1e-12)


def test_monte_carlo_and_probit_means_agree(data) -> None:
    from hapticframe_bhm import _functional as fn

    train, test = data
    bhm = build(monte_carlo_samples=200)
    bhm.fit(train)
    phi = bhm.features(test.points_m[:5000])
    draws = fn.sample_weights(bhm.belief, np.random.default_rng(9), 200)
    activations = fn.activation_samples(phi, draws)
    mc_mean, mc_std = fn.monte_carlo_probability(activations)
    estimate = bhm.query(test.points_m[:5000])
    assert np.mean(np.abs(mc_mean - estimate.mean)) < 0.01
    assert np.corrcoef(mc_std, estimate.std)[0, 1] > 0.9


def test_only_free_movement_data(scene) -> None:
    rng = np.random.default_rng(1)
    points = rng.uniform([0, 0], [0.75, 0.5], size=(1500, 2))
    bhm = build()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bhm.fit(Observations(points, np.zeros(1500)))
        estimate = bhm.query(points)
    assert np.all(estimate.mean < 0.5) and np.all(np.isfinite(estimate.std))
    assert not bhm.interaction_hinges.any()


@pytest.mark.parametrize("value", [0.0, 1.0])
def test_constant_soft_targets(value) -> None:
    rng = np.random.default_rng(2)
    points = rng.uniform([0.2, 0.1], [0.4, 0.3], size=(300, 2))
    bhm = build()
    bhm.fit(Observations(points, np.full(300, value)))
    mean = bhm.query(points).mean
    assert np.all(mean > 0.5) if value else np.all(mean < 0.5)


@pytest.mark.parametrize("scale", [1e-6, 1e-4, 10.0, 1e3])
def test_extreme_length_scales_stay_finite_without_warnings(data, scale) -> None:
    train, test = data
    bhm = build(length_scale_free_m=scale, length_scale_interaction_m=scale)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bhm.fit(train)
        estimate = bhm.query(test.points_m[:2000])
        _, _, mean, std = bhm.probability_grid(0.02)
    for values in (estimate.mean, estimate.std, mean, std):
        assert np.all(np.isfinite(values))
    assert np.all((estimate.mean >= 0) & (estimate.mean <= 1))


def test_zero_weight_observations_change_nothing(data) -> None:
    train, _ = data
    bhm = build()
    prior = bhm.query([[0.25, 0.25]]).mean
    bhm.update(Observations(train.points_m, train.targets, np.zeros(len(train))))
    np.testing.assert_allclose(bhm.belief.mean[:-1], 0.0, atol=1e-12)
    np.testing.assert_allclose(bhm.belief.mean[-1], np.log(0.05 / 0.95), atol=1e-12)
    np.testing.assert_allclose(bhm.query([[0.25, 0.25]]).mean, prior)


# --- region-dependent smoothing ---------------------------------------------------------------


def test_interaction_observations_switch_nearby_hinges(data) -> None:
    train, _ = data
    bhm = build(interaction_radius_m=0.05, **THESIS)
    free = train.targets < 0.5
    bhm.update(Observations(train.points_m[free], train.targets[free]))
    assert not bhm.interaction_hinges.any()
    assert np.all(bhm.length_scales == bhm.config.length_scale_free_m)
    hit = np.array([[0.30, 0.20]])
    bhm.update(Observations(hit, np.array([0.9])))
    hinges = np.stack(np.meshgrid(*bhm.hinge_axes, indexing="ij"), axis=-1)
    expected = np.hypot(hinges[..., 0] - 0.30, hinges[..., 1] - 0.20) <= 0.05
    np.testing.assert_array_equal(bhm.interaction_hinges, expected)
    np.testing.assert_allclose(
        bhm.length_scales[expected], bhm.config.length_scale_interaction_m
    )
    assert bhm.refits == 1
    # A refit is a fit of everything seen with the new length scales.
    everything = Observations.concatenate(
        [
            Observations(train.points_m[free], train.targets[free]),
            Observations(hit, np.array([0.9])),
        ]
    )
    fresh = build(interaction_radius_m=0.05, **THESIS)
    fresh.fit(everything)
    np.testing.assert_array_equal(fresh.interaction_hinges, bhm.interaction_hinges)
    np.testing.assert_allclose(fresh.belief.mean, bhm.belief.mean, rtol=1e-10, atol=1e-12)


def test_hinges_with_occupancy_above_one_half_switch_at_the_next_update() -> None:
    rng = np.random.default_rng(3)
    points = rng.uniform([0, 0], [0.75, 0.5], size=(3000, 2))
    targets = (np.hypot(points[:, 0] - 0.4, points[:, 1] - 0.25) < 0.05).astype(float)
    bhm = build(**{**THESIS, "interaction_radius_m": 0.0})  # rule (b) off
    bhm.fit(Observations(points, targets))
    assert not bhm.interaction_hinges.any()
    assert bhm.query([[0.4, 0.25]]).mean[0] > 0.5
    refits = bhm.refits
    bhm.update(Observations([[0.05, 0.05]], [0.0]))  # far away, free
    assert bhm.refits == refits + 1
    xs, ys = bhm.hinge_axes
    hinges = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)
    near_centre = np.hypot(hinges[..., 0] - 0.4, hinges[..., 1] - 0.25) < 0.03
    far = np.hypot(hinges[..., 0] - 0.4, hinges[..., 1] - 0.25) > 0.1
    assert np.all(bhm.interaction_hinges[near_centre])
    assert not bhm.interaction_hinges[far].any()


def test_plain_mode_never_switches(data) -> None:
    train, _ = data
    bhm = build(region_dependent_smoothing=False)
    bhm.fit(train)
    bhm.update(train)
    assert not bhm.interaction_hinges.any() and bhm.refits == 0


def test_reset_returns_to_the_prior(data) -> None:
    train, _ = data
    bhm = build(**THESIS)
    bhm.fit(train)
    assert bhm.interaction_hinges.any()
    bhm.reset()
    assert not bhm.interaction_hinges.any() and bhm.batches_fused == 0
    np.testing.assert_allclose(bhm.query([[0.25, 0.25]]).mean, 0.5)


# --- planner helpers, determinism, figures ------------------------------------------------------


@pytest.mark.parametrize("method", ["monte_carlo", "surrogate"])
@pytest.mark.parametrize("smoothing", [False, True])
def test_probability_grid_equals_query(data, method, smoothing) -> None:
    train, _ = data
    bhm = build(std_method=method, region_dependent_smoothing=smoothing)
    bhm.fit(train)
    xs, ys, mean, std = bhm.probability_grid(0.01)
    assert mean.shape == std.shape == (ys.size, xs.size) == (50, 75)
    points = np.stack(np.meshgrid(xs, ys, indexing="xy"), axis=-1).reshape(-1, 2)
    estimate = bhm.query(points)
    np.testing.assert_allclose(mean.ravel(), estimate.mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(std.ravel(), estimate.std, rtol=1e-7, atol=1e-10)
    log_odds = bhm.log_odds(points)
    np.testing.assert_allclose(log_odds, np.log(estimate.mean / (1 - estimate.mean)), rtol=1e-6)


def test_monte_carlo_std_is_seeded_and_stable_between_queries(data) -> None:
    train, test = data
    mc = {"std_method": "monte_carlo"}
    first, second, other = build(seed=4, **mc), build(seed=4, **mc), build(seed=5, **mc)
    for bhm in (first, second, other):
        bhm.fit(train)
    points = test.points_m[:500]
    np.testing.assert_array_equal(first.query(points).std, first.query(points).std)
    np.testing.assert_array_equal(first.query(points).std, second.query(points).std)
    assert not np.array_equal(first.query(points).std, other.query(points).std)


def test_finalize_writes_the_two_figures(tmp_path: Path, scene, data) -> None:
    train, _ = data
    bhm = build(scene=scene)
    bhm.fit(train)
    outcome = RunOutcome(tmp_path, scene, (), {"bhm": bhm}, 0.0)
    assert dict(bhm.finalize(outcome)) == {}
    for name in ("bhm_mean.png", "bhm_std.png"):
        assert (tmp_path / name).read_bytes().startswith(b"\x89PNG")
    bare = tmp_path / "bare"
    assert dict(build().finalize(RunOutcome(bare, None, (), {}, 0.0))) == {}
    assert (bare / "bhm_mean.png").exists() and (bare / "bhm_std.png").exists()
