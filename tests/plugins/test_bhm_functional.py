"""Numerics of the Bayesian Hilbert map (hapticframe_bhm._functional and ._separable)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize
from scipy.special import expit, log_expit

from hapticframe_bhm import _functional as fn
from hapticframe_bhm._separable import grid_activation_samples, grid_predictive_moments

# --- lambda(xi) -----------------------------------------------------------------------------


def _lambda_series(x: np.ndarray) -> np.ndarray:
    """Four terms of the Taylor series of tanh(x/2)/(4x); exact to < 1e-25 for |x| <= 1e-2."""
    x2 = x * x
    return 1 / 8 - x2 / 96 + x2 * x2 / 960 - 17 * x2**3 / 161280


def test_lambda_at_zero_is_exactly_one_eighth() -> None:
    assert fn.jj_lambda(0.0) == 0.125
    assert fn.jj_lambda(np.array([0.0, -0.0]))[1] == 0.125


def test_lambda_is_accurate_and_continuous_near_zero() -> None:
    edge = [1e-4 * (1 - 1e-12), 1e-4, 1e-4 * (1 + 1e-12)]
    xi = np.concatenate([np.logspace(-300, -2, 2000), edge])
    got = fn.jj_lambda(xi)
    np.testing.assert_allclose(got, _lambda_series(xi), rtol=2e-16 * 4, atol=0)
    # No jump where the implementation switches from the series to the tanh form.
    below, above = fn.jj_lambda(np.array([np.nextafter(1e-4, 0), 1e-4]))
    assert abs(below - above) < 1e-15
    assert np.all(np.diff(got[:-3]) <= 0)  # decreasing in |xi|


def test_lambda_matches_the_logistic_definition_and_is_even() -> None:
    xi = np.logspace(-2, 2.5, 200)
    reference = (expit(xi) - 0.5) / (2 * xi)
    np.testing.assert_allclose(fn.jj_lambda(xi), reference, rtol=1e-12)
    np.testing.assert_array_equal(fn.jj_lambda(-xi), fn.jj_lambda(xi))
    large = fn.jj_lambda(np.array([1e3, 1e300]))
    np.testing.assert_allclose(large, 1 / (4 * np.array([1e3, 1e300])), rtol=1e-12)


# --- hinges and features ---------------------------------------------------------------------


def test_hinge_axis_includes_both_edges_and_one_spacing_of_padding() -> None:
    axis = fn.hinge_axis(0.0, 0.75, 0.05)
    assert axis.size == 18
    np.testing.assert_allclose(axis[[0, 1, -2, -1]], [-0.05, 0.0, 0.75, 0.80], atol=1e-12)
    np.testing.assert_allclose(np.diff(axis), 0.05, atol=1e-12)
    odd = fn.hinge_axis(0.0, 0.12, 0.05)  # 0.12 is not a multiple of 0.05
    np.testing.assert_allclose(odd, [-0.05, 0.0, 0.05, 0.10, 0.15, 0.20], atol=1e-12)
    with pytest.raises(ValueError):
        fn.hinge_axis(0.0, 1.0, 0.0)
    with pytest.raises(ValueError):
        fn.hinge_axis(1.0, 1.0, 0.1)


def test_separable_features_equal_dense_features_with_mixed_length_scales() -> None:
    rng = np.random.default_rng(3)
    xs, ys = fn.hinge_axis(0, 0.3, 0.05), fn.hinge_axis(0, 0.2, 0.05)
    scales = np.full((xs.size, ys.size), 0.02)
    scales[2:5, 1:4] = 0.035
    scales[0, 0] = 0.01
    points = rng.uniform(-0.1, 0.4, size=(300, 2))
    hinges = fn.hinge_points(xs, ys)
    for bias in (False, True):
        fast = fn.separable_hinge_features(points, xs, ys, scales, bias)
        dense = fn.hinge_features(points, hinges, scales.ravel(), bias)
        np.testing.assert_allclose(fast, dense, rtol=1e-14, atol=1e-300)
    # A hand-computed entry: hinge (i, j) is column i * ny + j.
    x = np.array([[0.03, 0.07]])
    i, j = 3, 2
    expected = np.exp(-((0.03 - xs[i]) ** 2 + (0.07 - ys[j]) ** 2) / (2 * scales[i, j] ** 2))
    value = fn.hinge_features(x, hinges, scales.ravel())[0, i * ys.size + j]
    assert value == pytest.approx(expected)


def test_features_reject_bad_input_and_stay_finite_at_extreme_length_scales() -> None:
    hinges = np.array([[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(ValueError):
        fn.hinge_features([[np.nan, 0.0]], hinges, 0.1)
    with pytest.raises(ValueError):
        fn.hinge_features([[0.0, 0.0]], hinges, 0.0)
    with pytest.raises(ValueError):
        fn.hinge_features(np.zeros((3, 3)), hinges, 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tiny = fn.hinge_features([[0.0, 0.0], [1e6, -1e6]], hinges, 1e-12)
        huge = fn.hinge_features([[0.0, 0.0], [1e6, -1e6]], hinges, 1e12)
    np.testing.assert_array_equal(tiny, [[1.0, 0.0], [0.0, 0.0]])
    assert np.all(np.isfinite(huge)) and huge[0, 0] == 1.0 and huge[0, 1] == pytest.approx(1.0)


# --- variational EM against an independent dense reference ---------------------------------


def _reference_vb(phi, y, w, prior_var, iterations):
    """Textbook JJ variational EM with a fixed prior, written with explicit loops and inv()."""
    n, d = phi.shape
    s0_inv = np.eye(d) / prior_var
    xi = np.sqrt(prior_var * np.sum(phi**2, axis=1))  # prior predictive (zero prior mean)
    for _ in range(iterations):
        lam = (1 / (1 + np.exp(-xi)) - 0.5) / (2 * xi)
        precision = s0_inv.copy()
        rhs = np.zeros(d)
        for k in range(n):
            precision += 2 * w[k] * lam[k] * np.outer(phi[k], phi[k])
            rhs += w[k] * (y[k] - 0.5) * phi[k]
        cov = np.linalg.inv(precision)
        mean = cov @ rhs
        xi = np.sqrt(np.array([(phi[k] @ mean) ** 2 + phi[k] @ cov @ phi[k] for k in range(n)]))
    return mean, cov


@pytest.fixture
def small_problem():
    rng = np.random.default_rng(11)
    xs, ys = fn.hinge_axis(0, 0.2, 0.05), fn.hinge_axis(0, 0.1, 0.05)
    points = rng.uniform([0, 0], [0.2, 0.1], size=(60, 2))
    targets = (np.hypot(points[:, 0] - 0.1, points[:, 1] - 0.05) < 0.04).astype(float)
    targets[::7] = 0.3  # soft targets
    weights = rng.uniform(0.2, 2.0, size=60)
    phi = fn.separable_hinge_features(points, xs, ys, np.full((xs.size, ys.size), 0.025), True)
    return phi, targets, weights


@pytest.mark.parametrize("iterations", [1, 2, 7])
def test_variational_update_matches_dense_reference(small_problem, iterations) -> None:
    phi, targets, weights = small_problem
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 5.0)
    post, info = fn.variational_update(
        prior, phi, targets, weights, max_iterations=iterations, tolerance=0.0
    )
    mean, cov = _reference_vb(phi, targets, weights, 5.0, iterations)
    assert info.iterations == iterations
    np.testing.assert_allclose(post.mean, mean, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(post.covariance(), cov, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(post.variances(), np.diag(cov), rtol=1e-8)
    _mu, var = fn.predictive_moments(post, phi)
    np.testing.assert_allclose(var, np.einsum("ij,jk,ik->i", phi, cov, phi), rtol=1e-8)


def test_converged_vb_is_close_to_a_laplace_approximation(small_problem) -> None:
    """At convergence the JJ posterior mean is near the MAP of the same logistic model."""
    phi, targets, weights = small_problem
    prior_var = 5.0

    def negative_log_posterior(w):
        a = phi @ w
        ll = weights * (targets * log_expit(a) + (1 - targets) * log_expit(-a))
        return -ll.sum() + w @ w / (2 * prior_var)

    map_weights = minimize(negative_log_posterior, np.zeros(phi.shape[1]), method="BFGS").x
    prior = fn.GaussianWeights.isotropic(phi.shape[1], prior_var)
    post, info = fn.variational_update(
        prior, phi, targets, weights, max_iterations=500, tolerance=1e-10
    )
    assert info.converged
    p_vb = expit(phi @ post.mean)
    p_map = expit(phi @ map_weights)
    assert np.max(np.abs(p_vb - p_map)) < 0.05


def test_weight_variances_do_not_shrink_when_a_batch_is_iterated_longer() -> None:
    rng = np.random.default_rng(4)
    xs, ys = fn.hinge_axis(0, 0.2, 0.05), fn.hinge_axis(0, 0.1, 0.05)
    # Data over the whole padded hinge grid, so that every weight is informed.
    points = rng.uniform([-0.05, -0.05], [0.25, 0.15], size=(800, 2))
    targets = (np.hypot(points[:, 0] - 0.1, points[:, 1] - 0.05) < 0.04).astype(float)
    flip = rng.random(800) < 0.05
    targets[flip] = 1 - targets[flip]
    phi = fn.separable_hinge_features(points, xs, ys, np.full((xs.size, ys.size), 0.025), True)
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 100.0)
    # Starting from xi = 0 gives lambda = 1/8, its maximum, so the first posterior has the
    # largest possible precision. With the prior held fixed, later iterations only lower
    # lambda(xi): the variances can only grow, never shrink.
    start = np.zeros(len(targets))
    one, _ = fn.variational_update(prior, phi, targets, max_iterations=1, xi_initial=start)
    twenty, _ = fn.variational_update(
        prior, phi, targets, max_iterations=20, tolerance=0, xi_initial=start
    )
    assert np.median(one.variances()) < 10.0  # informed weights, far below the prior's 100
    assert np.all(twenty.variances() >= one.variances() * (1 - 1e-9))

    # Negative control: feeding each iteration's posterior back as the prior (as the public
    # reference code does) counts the batch 20 times and shrinks the variances, which the
    # assertion above would catch.
    accumulated = prior
    xi = start
    for _ in range(20):
        accumulated, _ = fn.variational_update(
            accumulated, phi, targets, max_iterations=1, xi_initial=xi
        )
        xi = fn.xi_from_belief(accumulated, phi)
    assert np.median(accumulated.variances() / one.variances()) < 0.4
    assert np.median(accumulated.variances() / twenty.variances()) < 0.25


def test_zero_weights_and_empty_batches_leave_the_prior_unchanged(small_problem) -> None:
    phi, targets, _ = small_problem
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 3.0)
    post, _ = fn.variational_update(prior, phi, targets, np.zeros(len(targets)))
    np.testing.assert_allclose(post.mean, 0.0, atol=1e-15)
    np.testing.assert_allclose(post.variances(), 3.0, rtol=1e-12)
    same, info = fn.variational_update(prior, phi[:0], targets[:0])
    assert same is prior and info.iterations == 0


def test_update_validates_its_inputs(small_problem) -> None:
    phi, targets, weights = small_problem
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 3.0)
    bad_targets = targets.copy()
    bad_targets[0] = np.nan
    with pytest.raises(ValueError):
        fn.variational_update(prior, phi, bad_targets)
    with pytest.raises(ValueError):
        fn.variational_update(prior, phi, targets + 1.5)
    with pytest.raises(ValueError):
        fn.variational_update(prior, phi, targets, -weights)
    with pytest.raises(ValueError):
        fn.variational_update(prior, phi[:, :-1], targets)
    with pytest.raises(ValueError):
        fn.variational_update(prior, phi, targets, max_iterations=0)


def test_one_hinge_problem_matches_reference() -> None:
    rng = np.random.default_rng(5)
    points = rng.uniform(-0.05, 0.05, size=(40, 2))
    phi = fn.hinge_features(points, [[0.0, 0.0]], 0.03)
    targets = (rng.random(40) < 0.8).astype(float)
    prior = fn.GaussianWeights.isotropic(1, 10.0)
    post, _ = fn.variational_update(prior, phi, targets, max_iterations=4, tolerance=0)
    mean, cov = _reference_vb(phi, targets, np.ones(40), 10.0, 4)
    np.testing.assert_allclose(post.mean, mean, rtol=1e-10)
    np.testing.assert_allclose(post.covariance(), cov, rtol=1e-10)
    assert post.mean[0] > 0  # mostly occupied targets


@pytest.mark.parametrize("value", [0.0, 1.0])
def test_constant_targets_give_finite_confident_maps(small_problem, value) -> None:
    phi, targets, _ = small_problem
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        post, _ = fn.variational_update(prior, phi, np.full(len(targets), value))
        mu, var = fn.predictive_moments(post, phi)
        p = fn.probit_probability(mu, var)
    assert np.all(np.isfinite(post.mean)) and np.all(np.isfinite(var))
    assert np.all(p < 0.5) if value == 0.0 else np.all(p > 0.5)


def test_cholesky_with_jitter() -> None:
    singular = np.ones((3, 3))  # PSD, rank 1
    lower = fn.cholesky_with_jitter(singular)
    np.testing.assert_allclose(lower @ lower.T, singular, atol=1e-6)
    with pytest.raises(np.linalg.LinAlgError):
        fn.cholesky_with_jitter(-np.eye(3))
    with pytest.raises(np.linalg.LinAlgError):
        fn.cholesky_with_jitter(np.full((2, 2), np.nan))


# --- prediction -------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(
    mu=st.floats(-1e6, 1e6, allow_nan=False),
    var=st.floats(0, 1e12, allow_nan=False),
)
def test_probit_and_surrogate_stay_in_range(mu: float, var: float) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p = fn.probit_probability(np.array([mu]), np.array([var]))
        s = fn.surrogate_std(np.array([mu]), np.array([var]))
    assert 0.0 <= p[0] <= 1.0
    assert 0.0 <= s[0] <= 0.5 and np.isfinite(s[0])


def test_probit_reduces_to_the_sigmoid_without_variance_and_flattens_with_it() -> None:
    mu = np.linspace(-5, 5, 11)
    np.testing.assert_allclose(fn.probit_probability(mu, np.zeros(11)), expit(mu))
    flattened = fn.probit_probability(mu, np.full(11, 100.0))
    assert np.all(np.abs(flattened - 0.5) < np.abs(expit(mu) - 0.5) + 1e-15)


def test_monte_carlo_mean_agrees_with_probit_mean() -> None:
    rng = np.random.default_rng(2)
    mu = rng.normal(0, 3, size=2000)
    var = rng.uniform(0, 6, size=2000)
    samples = mu[:, None] + np.sqrt(var)[:, None] * rng.standard_normal((2000, 4000))
    mc_mean, mc_std = fn.monte_carlo_probability(samples)
    p = fn.probit_probability(mu, var)
    assert np.mean(np.abs(mc_mean - p)) < 0.01
    # The surrogate tracks the Monte-Carlo std.
    assert np.corrcoef(mc_std, fn.surrogate_std(mu, var))[0, 1] > 0.95
    with pytest.raises(ValueError):
        fn.monte_carlo_probability(np.zeros((3, 1)))


def test_weight_samples_have_the_belief_moments(small_problem) -> None:
    phi, targets, weights = small_problem
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 5.0)
    post, _ = fn.variational_update(prior, phi, targets, weights)
    draws = fn.sample_weights(post, np.random.default_rng(0), 200_000)
    np.testing.assert_allclose(draws.mean(axis=1), post.mean, atol=0.05)
    np.testing.assert_allclose(np.cov(draws), post.covariance(), atol=0.05)
    again = fn.sample_weights(post, np.random.default_rng(0), 10)
    np.testing.assert_array_equal(again, fn.sample_weights(post, np.random.default_rng(0), 10))


@pytest.mark.parametrize("bias", [False, True])
@pytest.mark.parametrize("mixed", [False, True])
def test_separable_grid_prediction_equals_dense_prediction(bias: bool, mixed: bool) -> None:
    rng = np.random.default_rng(8)
    xs, ys = fn.hinge_axis(0, 0.3, 0.05), fn.hinge_axis(0, 0.2, 0.05)
    scales = np.full((xs.size, ys.size), 0.022)
    if mixed:
        scales[3:6, 2:5] = 0.035
    points = rng.uniform([0, 0], [0.3, 0.2], size=(400, 2))
    targets = (np.hypot(points[:, 0] - 0.15, points[:, 1] - 0.1) < 0.05).astype(float)
    phi = fn.separable_hinge_features(points, xs, ys, scales, bias)
    prior = fn.GaussianWeights.isotropic(phi.shape[1], 10.0)
    qx, qy = np.linspace(-0.05, 0.35, 23), np.linspace(-0.02, 0.22, 17)
    grid = np.stack(np.meshgrid(qx, qy, indexing="xy"), axis=-1).reshape(-1, 2)
    for belief in (prior, fn.variational_update(prior, phi, targets)[0]):
        mu, var = grid_predictive_moments(qx, qy, xs, ys, scales, belief, bias)
        dense_mu, dense_var = fn.predictive_moments(
            belief, fn.separable_hinge_features(grid, xs, ys, scales, bias)
        )
        assert mu.shape == (qy.size, qx.size)
        np.testing.assert_allclose(mu.ravel(), dense_mu, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(var.ravel(), dense_var, rtol=1e-8, atol=1e-11)
        draws = fn.sample_weights(belief, np.random.default_rng(1), 7)
        act = grid_activation_samples(qx, qy, xs, ys, scales, draws, bias)
        dense_act = fn.separable_hinge_features(grid, xs, ys, scales, bias) @ draws
        np.testing.assert_allclose(act.reshape(-1, 7), dense_act, rtol=1e-9, atol=1e-9)
