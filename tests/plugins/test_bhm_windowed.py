"""Windowed feature rows, the cached covariance and the grid fast path of the BHM."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from hapticframe.geometry import sample_grid
from hapticframe.kinds import BuildContext, Observations
from hapticframe_bench import labelled_points, two_object_scene
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_bhm import _functional as fn
from hapticframe_bhm._dense import grid_axes as _grid_axes
from hapticframe_bhm._windowed import (
    TRUNCATION,
    DenseRows,
    WindowedRows,
    window_half_width,
)

XS = fn.hinge_axis(0.0, 0.75, 0.05)
YS = fn.hinge_axis(0.0, 0.50, 0.05)


def points(rng: np.random.Generator, n: int) -> np.ndarray:
    inside = rng.uniform([0.0, 0.0], [0.75, 0.5], size=(n, 2))
    # Some beyond the hinge grid, and one very far away: windows clip at the grid's edge.
    inside[:5] = [[-0.2, 0.1], [0.9, 0.6], [0.3, -0.1], [1e6, -1e6], [0.75, 0.5]]
    return inside


@pytest.mark.parametrize("length_scale", [0.02, 0.033, 0.045])
def test_windows_keep_every_feature_above_the_truncation(length_scale) -> None:
    rng = np.random.default_rng(0)
    p = points(rng, 400)
    half = window_half_width(length_scale, 0.05)
    rows = WindowedRows(p, XS, YS, length_scale, False, half)
    dense = fn.separable_hinge_features(p, XS, YS, np.full((XS.size, YS.size), length_scale))
    kept = np.zeros_like(dense, dtype=bool)
    order = rows.order
    kept[order[:, None], rows.columns[rows.group]] = True
    assert dense[~kept].max() < TRUNCATION
    np.testing.assert_allclose(dense[order[:, None], rows.columns[rows.group]], rows.rows,
                               rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("bias", [False, True])
def test_windowed_reductions_match_dense_ones(bias) -> None:
    rng = np.random.default_rng(1)
    p = points(rng, 1500)
    scale = 0.033
    rows = WindowedRows(p, XS, YS, scale, bias, window_half_width(scale, 0.05))
    dense = DenseRows(fn.separable_hinge_features(
        p, XS, YS, np.full((XS.size, YS.size), scale), bias))
    assert rows.dimension == dense.dimension and rows.count == dense.count == 1500
    d = dense.dimension
    c = rng.uniform(0.0, 0.25, 1500)
    v = rng.standard_normal(1500)
    m = rng.standard_normal(d)
    a = rng.standard_normal((d, d))
    s = a @ a.T / d + np.eye(d)
    tol = 50 * TRUNCATION
    np.testing.assert_allclose(rows.gram(c), dense.gram(c), atol=tol * c.sum())
    np.testing.assert_allclose(rows.weighted_sum(v), dense.weighted_sum(v),
                               atol=tol * np.abs(v).sum())
    np.testing.assert_allclose(rows.dot(m), dense.dot(m), atol=tol * np.abs(m).sum())
    np.testing.assert_allclose(rows.quadratic(s), dense.quadratic(s), rtol=1e-4)
    diag = rng.uniform(0.5, 2.0, d)
    np.testing.assert_allclose(rows.quadratic_diagonal(diag), dense.quadratic_diagonal(diag),
                               rtol=1e-4)


def test_window_must_fit_and_width_grows_with_length_scale() -> None:
    assert window_half_width(0.02, 0.05) < window_half_width(0.05, 0.05)
    with pytest.raises(ValueError):
        window_half_width(0.0, 0.05)
    with pytest.raises(ValueError, match="fit"):
        WindowedRows(np.zeros((3, 2)), XS[:4], YS[:4], 0.033, True, 3)


def test_empty_windowed_rows() -> None:
    rows = WindowedRows(np.empty((0, 2)), XS, YS, 0.033, True, 3)
    assert rows.count == 0
    np.testing.assert_array_equal(rows.gram(np.empty(0)), np.zeros((rows.dimension,) * 2))
    assert rows.dot(np.zeros(rows.dimension)).shape == (0,)


def test_covariance_is_the_inverse_precision_and_cached() -> None:
    rng = np.random.default_rng(2)
    a = rng.standard_normal((300, 40))
    belief = fn.GaussianWeights.from_information(a.T @ a + np.eye(40), rng.standard_normal(40))
    cov = belief.covariance()
    expected = sla.cho_solve((belief.cholesky, True), np.eye(40))
    np.testing.assert_allclose(cov, expected, rtol=1e-10, atol=1e-13)
    np.testing.assert_array_equal(cov, cov.T)
    assert belief.covariance() is cov and not cov.flags.writeable
    prior = fn.GaussianWeights.isotropic(5, 2.0, mean=[0.0, 0.0, 0.0, 0.0, -1.0])
    np.testing.assert_allclose(prior.covariance(), 2.0 * np.eye(5))
    np.testing.assert_allclose(prior.mean, [0, 0, 0, 0, -1.0])
    np.testing.assert_allclose(prior.shift, prior.precision @ prior.mean)


def test_windowed_fit_matches_a_dense_fit() -> None:
    scene = two_object_scene()
    data = labelled_points(scene, 3000, np.random.default_rng(3))
    config = BayesianHilbertMapConfig()
    windowed = BayesianHilbertMap(config, BuildContext("w", np.random.default_rng(0), scene=scene))
    windowed.fit(data)
    rows = DenseRows(windowed.features(data.points_m))
    belief, _ = fn.variational_update(
        windowed.prior, rows, data.targets, data.weights,
        max_iterations=config.max_iterations_first, tolerance=config.tolerance,
    )
    np.testing.assert_allclose(windowed.belief.mean, belief.mean, rtol=1e-4, atol=1e-4)


def test_grid_shaped_queries_take_the_separable_path_with_the_same_values() -> None:
    scene = two_object_scene()
    bhm = BayesianHilbertMap(
        BayesianHilbertMapConfig(), BuildContext("g", np.random.default_rng(0), scene=scene)
    )
    bhm.fit(labelled_points(scene, 1500, np.random.default_rng(4)))
    xs, ys, grid = sample_grid((0.0, 0.75, 0.0, 0.5), 0.01)
    axes = _grid_axes(grid)
    assert axes is not None
    np.testing.assert_array_equal(axes[0], xs)
    np.testing.assert_array_equal(axes[1], ys)
    fast = bhm.query(grid)
    shuffled = np.random.default_rng(5).permutation(grid.shape[0])
    assert _grid_axes(grid[shuffled]) is None
    slow = bhm.query(grid[shuffled])
    np.testing.assert_allclose(fast.mean[shuffled], slow.mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.std[shuffled], slow.std, rtol=1e-7, atol=1e-10)
    # Not grids: a single row, too few points, a ragged last row.
    assert _grid_axes(grid[:75]) is None
    assert _grid_axes(grid[:10]) is None
    assert _grid_axes(grid[:-3]) is None


def test_observations_far_away_change_no_hinge_weight() -> None:
    # Without the bias feature (which sees every point) nothing reaches them.
    scene = two_object_scene()
    bhm = BayesianHilbertMap(
        BayesianHilbertMapConfig(bias=False), BuildContext("f", np.random.default_rng(0),
                                                           scene=scene)
    )
    before = bhm.query([[0.3, 0.2]]).mean
    far = np.full((1200, 2), 1e6)
    bhm.update(Observations(far, np.ones(1200)))
    np.testing.assert_allclose(bhm.query([[0.3, 0.2]]).mean, before, atol=1e-9)
    np.testing.assert_allclose(bhm.belief.mean, 0.0, atol=1e-9)



def test_a_coarse_grid_is_queried_point_by_point_with_the_separable_paths_values(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # A large map's snapshot asks a tile for a few cells: a triangular solve per cell costs
    # less than the full covariance the separable path needs, and gives the same values.
    from hapticframe_bhm import _dense

    scene = two_object_scene()
    bhm = BayesianHilbertMap(
        BayesianHilbertMapConfig(), BuildContext("c", np.random.default_rng(0), scene=scene)
    )
    bhm.fit(labelled_points(scene, 1500, np.random.default_rng(4)))
    belief = bhm.belief
    # An update that stops at its iteration cap leaves no covariance behind: as if so.
    belief._cache.pop("covariance", None)
    assert not belief.has_covariance
    _, _, grid = sample_grid((0.0, 0.75, 0.0, 0.5), 0.075)  # 10 x 7 cells
    assert _grid_axes(grid) is not None and 3 * grid.shape[0] < belief.dimension

    def no_separable(*args: object, **kwargs: object) -> None:
        raise AssertionError("the separable path was taken")

    with monkeypatch.context() as patch:
        patch.setattr(_dense, "grid_predictive_moments", no_separable)
        coarse = bhm.query(grid)
    assert not belief.has_covariance  # nothing O(D^3) was computed
    belief.covariance()
    assert belief.has_covariance  # now the separable path costs the least: it is taken
    separable = bhm.query(grid)
    np.testing.assert_allclose(coarse.mean, separable.mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(coarse.std, separable.std, rtol=1e-7, atol=1e-10)
