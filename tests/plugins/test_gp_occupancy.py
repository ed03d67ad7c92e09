"""The ``gp-occupancy`` map (hapticframe_gp_occupancy): the kit, accuracy, extremes."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import Circle, RegionConfig, Scene, ValidationContext
from hapticframe.kinds import BuildContext, Map, Observations, RunOutcome
from hapticframe.testing import make_component, run_checks
from hapticframe_gp_occupancy import GPOccupancyConfig, GPOccupancyMap
from hapticframe_gp_occupancy import _checks as checks
from hapticframe_gp_occupancy import _functional as fn
from hapticframe_gp_occupancy import plugin as gp_plugin

SPEC = next(iter(gp_plugin.hapticframe_maps()))
#: A 75 x 50 cm region with one 8 cm disc.
SCENE = Scene(objects=[Circle(center_m=(0.40, 0.25), radius_m=0.04)])
CONTEXT = ValidationContext(id="gp", inputs={}, components={}, scene=None, run=None)


def build(scene: Scene | None = SCENE, **config) -> GPOccupancyMap:
    context = BuildContext(id="gp", rng=np.random.default_rng(0), scene=scene)
    return GPOccupancyMap(GPOccupancyConfig(**config), context)


def labelled(seed: int, count: int, flip: float = 0.03, scene: Scene = SCENE) -> Observations:
    rng = np.random.default_rng(seed)
    region = scene.region.to_region()
    points = np.column_stack([rng.uniform(region.x_min_m, region.x_max_m, count),
                              rng.uniform(region.y_min_m, region.y_max_m, count)])
    labels = scene.occupied(points).astype(np.float64)
    flipped = rng.random(count) < flip
    labels[flipped] = 1.0 - labels[flipped]
    return Observations(points, labels)


def auc(truth: np.ndarray, score: np.ndarray) -> float:
    pos, neg = score[truth], score[~truth]
    return float(np.mean(pos[:, None] > neg[None, :]) + 0.5 * np.mean(pos[:, None] == neg[None, :]))


# --- the kit ------------------------------------------------------------------------------------


def test_the_kit_map_checks_pass() -> None:
    results = run_checks(SPEC)
    failed = [r for r in results if r.status not in ("PASS", "SKIP")]
    assert not failed, failed
    names = {r.check for r in results}
    assert {"check_map_contract", "check_map_streaming_matches_batch", "check_map_extremes",
            "check_map_ranks_scattered_points", "check_deterministic", "check_knobs",
            "check_lazy_import"} <= names


def test_the_kit_builds_it_as_a_map() -> None:
    the_map = make_component(SPEC, interface=Map)
    assert isinstance(the_map, GPOccupancyMap)
    assert the_map.region.size_m == pytest.approx((0.75, 0.5))


# --- numerics -----------------------------------------------------------------------------------


def test_exact_posterior_equals_scikit_learn() -> None:
    """Mean and std of the exact path match sklearn's GaussianProcessRegressor (same kernel,
    per-point noise, no optimiser)."""
    pytest.importorskip("sklearn")
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel

    obs = labelled(1, 120)
    weights = np.random.default_rng(2).uniform(0.5, 2.0, 120)
    noise = 0.25 / weights
    targets = fn.latent_targets(obs.targets)
    posterior = fn.exact_posterior(obs.points_m, targets, noise, 0.03, 0.8)
    queries = labelled(3, 50).points_m
    mu, var = fn.exact_predict(posterior, queries, 0.03, 0.8)
    reference = GaussianProcessRegressor(ConstantKernel(0.8) * RBF(0.03), alpha=noise,
                                         optimizer=None).fit(obs.points_m, targets)
    ref_mu, ref_std = reference.predict(queries, return_std=True)
    np.testing.assert_allclose(mu, ref_mu, atol=1e-6)
    np.testing.assert_allclose(np.sqrt(var), ref_std, atol=1e-6)


def test_inducing_points_at_the_data_recover_the_exact_posterior() -> None:
    """DTC with the training points as inducing points is the exact GP."""
    obs = labelled(4, 60)
    targets = fn.latent_targets(obs.targets)
    precisions = np.full(60, 4.0)
    exact = fn.exact_posterior(obs.points_m, targets, 1.0 / precisions, 0.04, 1.0)
    s, r = fn.inducing_statistics(obs.points_m, obs.points_m, targets, precisions, 0.04, 1.0)
    sparse = fn.inducing_posterior(obs.points_m, s, r, 0.04, 1.0)
    queries = labelled(5, 40).points_m
    np.testing.assert_allclose(fn.inducing_predict(sparse, queries, 0.04, 1.0),
                               fn.exact_predict(exact, queries, 0.04, 1.0), atol=1e-5)


def test_probit_moments_match_sampling() -> None:
    rng = np.random.default_rng(6)
    mu, var = np.array([-1.2, 0.0, 0.4, 2.0]), np.array([0.05, 1.0, 0.3, 2.5])
    mean, std = fn.probit_moments(mu, var, 3.0)
    from scipy.special import ndtr

    samples = ndtr(3.0 * (mu + np.sqrt(var) * rng.standard_normal((200_000, 4))))
    np.testing.assert_allclose(mean, samples.mean(0), atol=3e-3)
    np.testing.assert_allclose(std, samples.std(0), atol=3e-3)
    # No latent variance: a point mass, std 0.
    assert fn.probit_moments(np.array([0.7]), np.array([0.0]), 3.0)[1][0] == pytest.approx(0.0)


# --- accuracy on a known scene ------------------------------------------------------------------


@pytest.mark.parametrize("method", ["exact", "inducing"])
def test_recovers_the_disc(method: str) -> None:
    the_map = build(method=method)
    the_map.update(labelled(10, 1500))
    assert the_map.method_in_use == method
    probe = labelled(11, 2000, flip=0.0)
    estimate = the_map.query(probe.points_m)
    truth = probe.targets > 0.5
    assert auc(truth, estimate.mean) > 0.99
    # The 0.5 level set: few mislabelled points, all of them near the rim.
    wrong = (estimate.mean > 0.5) != truth
    assert wrong.mean() < 0.01
    rim = np.abs(np.linalg.norm(probe.points_m - (0.40, 0.25), axis=1) - 0.04)
    assert rim[wrong].max(initial=0.0) < 0.015
    # Confident inside and far away; the std is largest near the rim.
    centre = the_map.query(np.array([[0.40, 0.25], [0.10, 0.10]]))
    assert centre.mean[0] > 0.9 and centre.mean[1] < 0.1
    assert estimate.std[rim < 0.005].mean() > 2 * estimate.std[rim > 0.05].mean()


def test_auto_switches_to_inducing_points_and_streams_like_a_fit() -> None:
    first, second = labelled(20, 300), labelled(21, 300)
    streamed = build(exact_max_observations=400)
    streamed.update(first)
    assert streamed.method_in_use == "exact"
    streamed.update(second)
    assert streamed.method_in_use == "inducing"
    fitted = build(exact_max_observations=400)
    fitted.fit(Observations.concatenate([first, second]))
    grid = labelled(22, 300).points_m
    np.testing.assert_allclose(streamed.query(grid).mean, fitted.query(grid).mean, atol=1e-9)
    # Inducing points are close to the exact GP on the same data.
    exact = build(method="exact")
    exact.fit(Observations.concatenate([first, second]))
    assert np.max(np.abs(exact.query(grid).mean - fitted.query(grid).mean)) < 0.1


def test_weights_scale_the_evidence() -> None:
    point = np.array([[0.2, 0.2]])
    heavy, light, ignored = build(), build(), build()
    heavy.update(Observations(point, [1.0], [5.0]))
    light.update(Observations(point, [1.0], [0.2]))
    ignored.update(Observations(point, [1.0], [0.0]))
    assert heavy.query(point).mean[0] > light.query(point).mean[0] > 0.5
    assert ignored.observation_count == 0
    assert ignored.query(point).mean[0] == pytest.approx(0.5)


def test_learned_hyperparameters_come_from_scikit_learn() -> None:
    pytest.importorskip("sklearn")
    the_map = build(learn_hyperparameters=True, method="exact")
    the_map.update(labelled(30, 250))
    the_map.query(np.array([[0.3, 0.3]]))
    learned = the_map.hyperparameters
    assert learned["length_scale_m"] != pytest.approx(0.03)
    assert 0.003 <= learned["length_scale_m"] <= 0.3
    the_map.reset()
    assert the_map.hyperparameters["length_scale_m"] == 0.03


# --- extremes -----------------------------------------------------------------------------------


def test_empty_map_is_the_prior() -> None:
    the_map = build(prior_occupancy=0.3)
    the_map.update(Observations.empty())
    estimate = the_map.query(np.array([[0.1, 0.1], [5.0, -3.0]]))
    np.testing.assert_allclose(estimate.mean, 0.3, atol=1e-12)
    assert np.all(estimate.std > 0.1)
    assert the_map.query(np.empty((0, 2))).mean.shape == (0,)
    assert the_map.method_in_use == "prior"


@pytest.mark.parametrize("method", ["exact", "inducing"])
def test_one_observation(method: str) -> None:
    the_map = build(method=method)
    the_map.update(Observations([[0.3, 0.2]], [1.0]))
    near, far = the_map.query(np.array([[0.3, 0.2], [0.6, 0.4]])).mean
    assert near > 0.7
    assert far == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize("value", [0.0, 1.0])
def test_constant_targets(value: float) -> None:
    obs = labelled(40, 400)
    for method in ("exact", "inducing"):
        the_map = build(method=method)
        the_map.update(Observations(obs.points_m, np.full(len(obs), value)))
        mean = the_map.query(labelled(41, 200).points_m).mean
        assert np.all(np.isfinite(mean))
        # Never the wrong side of 0.5; confident where the data are dense.
        side = mean if value else 1.0 - mean
        assert np.all(side > 0.5) and np.median(side) > 0.9


def test_nan_is_refused() -> None:
    the_map = build()
    the_map.update(labelled(50, 20))
    with pytest.raises(ValueError, match="NaN"):
        the_map.query(np.array([[np.nan, 0.1]]))
    with pytest.raises(ValueError, match="NaN"):
        Observations([[np.nan, 0.1]], [1.0])
    with pytest.raises(TypeError, match="Observations"):
        the_map.update(np.zeros((3, 2)))  # type: ignore[arg-type]


def test_far_and_repeated_observations_stay_finite() -> None:
    the_map = build(method="exact")
    the_map.update(Observations(np.full((200, 2), 1e6), np.ones(200)))
    the_map.update(Observations(np.repeat([[0.3, 0.3]], 300, axis=0), np.ones(300)))
    estimate = the_map.query(np.array([[1e6, 1e6], [0.3, 0.3], [0.7, 0.1]]))
    assert np.all(np.isfinite(estimate.mean)) and np.all(np.isfinite(estimate.std))
    assert estimate.mean[0] > 0.9 and estimate.mean[1] > 0.9


# --- configuration and validation ---------------------------------------------------------------


def test_config_refuses_a_prior_beyond_the_targets() -> None:
    with pytest.raises(ValidationError, match="prior_occupancy"):
        GPOccupancyConfig(prior_occupancy=0.02)
    with pytest.raises(ValidationError):
        GPOccupancyConfig(length_scale_m=float("nan"))


def test_too_many_inducing_points_are_refused_at_validation_and_build() -> None:
    config = GPOccupancyConfig(region=RegionConfig(x_min_m=0, x_max_m=10, y_min_m=0, y_max_m=10))
    from hapticframe import Finding

    findings = [f for f in checks.check(config, CONTEXT) if isinstance(f, Finding)]
    assert len(findings) == 1 and "inducing_spacing_m" in findings[0].message
    with pytest.raises(ValueError, match="max_inducing_points"):
        GPOccupancyMap(config, BuildContext(id="big", rng=np.random.default_rng(0)))
    # Only the sizes it declares (within the limits) for the defaults.
    assert all(f.problem() is None for f in checks.check(GPOccupancyConfig(), CONTEXT)
               if not isinstance(f, Finding))
    assert not [f for f in checks.check(GPOccupancyConfig(), CONTEXT) if isinstance(f, Finding)]
    assert checks.inducing_count(0.75, 0.5, 0.025) == build().inducing_points.shape[0]


def test_figures_are_written(tmp_path) -> None:
    pytest.importorskip("matplotlib")
    the_map = build()
    the_map.update(labelled(60, 200))
    the_map.finalize(RunOutcome(out_dir=tmp_path, scene=SCENE, movements=(), components={},
                                wall_time_s=0.0))
    assert (tmp_path / "gp_mean.png").stat().st_size > 0
    assert (tmp_path / "gp_std.png").stat().st_size > 0
