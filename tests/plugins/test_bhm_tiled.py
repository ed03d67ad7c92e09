"""Local posteriors of the Bayesian Hilbert map (hapticframe_bhm._tiled, issue 19 §5)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe import RegionConfig, Scene
from hapticframe.kinds import BuildContext, Observations
from hapticframe_bench import labelled_points, two_object_scene
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_bhm._tiled import TileLayout
from hapticframe_bhm._windowed import window_half_width


def build(seed: int = 0, scene: Scene | None = None, **config) -> BayesianHilbertMap:
    context = BuildContext(id="bhm", rng=np.random.default_rng(seed), scene=scene)
    return BayesianHilbertMap(BayesianHilbertMapConfig(**config), context)


@pytest.fixture(scope="module")
def data() -> tuple[Observations, Observations]:
    rng = np.random.default_rng(3)
    scene = two_object_scene()
    return labelled_points(scene, 2000, rng), labelled_points(scene, 4000, rng, 0.0)


def test_the_sandbox_keeps_one_dense_posterior_and_large_regions_are_tiled() -> None:
    assert build().tiled is None and build().belief.dimension == 235
    region = RegionConfig(x_min_m=0.0, x_max_m=10.0, y_min_m=0.0, y_max_m=10.0)
    large = build(region=region)
    assert large.tiled is not None
    layout = large.tiled.layout
    assert (layout.core, layout.halo) == (12, 6)  # 3.3 cm kernel, 5 cm hinges: w = 3
    assert layout.largest_tile_hinges() == 24 * 24
    with pytest.raises(AttributeError, match="tiled"):
        _ = large.belief


def test_every_point_is_fused_whole_into_its_owner_and_its_neighbours() -> None:
    layout = TileLayout(40, 30, core=6, reach=2)
    rng = np.random.default_rng(0)
    ix, iy = rng.integers(0, 40, 500), rng.integers(0, 30, 500)
    fused: dict[int, set[tuple[int, int]]] = {n: set() for n in range(500)}
    for tile, rows in layout.fusing(ix, iy):
        sx, sy = layout.hinge_range(tile)
        # The point's whole window (+-reach, clipped to the grid) lies inside the tile.
        assert np.all(np.maximum(ix[rows] - 2, 0) >= sx.start)
        assert np.all(np.minimum(ix[rows] + 2, 39) < sx.stop)
        assert np.all(np.maximum(iy[rows] - 2, 0) >= sy.start)
        assert np.all(np.minimum(iy[rows] + 2, 29) < sy.stop)
        for row in rows:
            fused[int(row)].add(tile)
    owners = layout.owners(ix, iy)
    for n in range(500):
        assert divmod(int(owners[n]), layout.tiles_y) in fused[n]
        assert 1 <= len(fused[n]) <= 4  # the core (6) is wider than a window (5)


def test_tiles_agree_with_the_dense_posterior(data) -> None:
    train, test = data
    dense = build()
    tiled = build(dense_weights_max=50, tile_size_m=0.2)
    assert tiled.tiled is not None and len(tiled.tiled.tiles) == 0
    for start in range(0, 2000, 500):  # sequential batches, as in a search
        rows = slice(start, start + 500)
        batch = Observations(train.points_m[rows], train.targets[rows])
        dense.update(batch)
        tiled.update(batch)
    a, b = dense.query(test.points_m), tiled.query(test.points_m)
    assert np.max(np.abs(a.mean - b.mean)) < 0.05
    assert np.mean(np.abs(a.mean - b.mean)) < 0.005
    assert np.mean(np.abs(a.std - b.std)) < 0.005
    labels = test.targets > 0.5
    assert np.mean((b.mean > 0.5) == labels) > 0.95


def test_grids_queries_and_log_odds_agree_and_unobserved_tiles_are_the_prior(data) -> None:
    train, _ = data
    region = RegionConfig(x_min_m=0.0, x_max_m=3.0, y_min_m=0.0, y_max_m=2.0)
    bhm = build(region=region)
    bhm.update(train)  # data only in the 0.75 x 0.5 m corner
    assert bhm.tiled is not None and len(bhm.tiled.tiles) == 4
    xs, ys, mean, std = bhm.probability_grid(0.02)
    points = np.column_stack([g.ravel() for g in np.meshgrid(xs, ys, indexing="xy")])
    estimate = bhm.query(points[::7])
    np.testing.assert_allclose(mean.ravel()[::7], estimate.mean, atol=1e-9)
    np.testing.assert_allclose(std.ravel()[::7], estimate.std, atol=1e-9)
    logit = np.log(estimate.mean / (1 - estimate.mean))
    np.testing.assert_allclose(bhm.log_odds(points[::7]), logit, atol=1e-6)
    # Far from the data: exactly what an untouched dense map says there.
    far = np.array([[2.5, 1.5], [1.8, 0.3]])
    fresh = build(region=RegionConfig(x_min_m=1.5, x_max_m=2.9, y_min_m=0.1, y_max_m=1.9))
    np.testing.assert_allclose(bhm.query(far).mean, fresh.query(far).mean, rtol=1e-9)
    np.testing.assert_allclose(bhm.query(far).std, fresh.query(far).std, rtol=1e-6)
    assert bhm.length_scales.shape == (63, 43) and not bhm.interaction_hinges.any()
    bhm.reset()
    assert not bhm.tiled.tiles


def test_a_ten_metre_region_holds_only_the_tiles_it_observed() -> None:
    region = RegionConfig(x_min_m=0.0, x_max_m=10.0, y_min_m=0.0, y_max_m=10.0)
    bhm = build(region=region)
    line = np.column_stack([np.linspace(4.0, 6.0, 400), np.full(400, 5.0)])
    bhm.update(Observations(line, np.zeros(400)))
    assert bhm.tiled is not None and 4 <= len(bhm.tiled.tiles) <= 10
    estimate = bhm.query(np.array([[5.0, 5.0], [9.0, 9.0]]))
    assert estimate.mean[0] < estimate.mean[1] < 0.5  # observed free, prior elsewhere
    xs, ys, mean, _ = bhm.probability_grid(0.05)
    assert mean.shape == (ys.size, xs.size) and np.all(np.isfinite(mean))


def test_region_dependent_smoothing_and_monte_carlo_run_per_tile(data) -> None:
    train, test = data
    bhm = build(dense_weights_max=50, tile_size_m=0.2, region_dependent_smoothing=True,
                std_method="monte_carlo", monte_carlo_samples=20)
    bhm.update(train)
    assert bhm.refits >= 1 and bhm.interaction_hinges.any()
    estimate = bhm.query(test.points_m[:500])
    assert np.all((estimate.std >= 0) & np.isfinite(estimate.std))
    assert window_half_width(float(bhm.length_scales.max()), 0.05) <= bhm.tiled.layout.reach


def test_packed_tiles_answer_as_before(data, monkeypatch) -> None:
    train, test = data
    whole = build(dense_weights_max=50, tile_size_m=0.1)
    whole.update(train)
    expected = whole.query(test.points_m[:1000])
    monkeypatch.setattr("hapticframe_bhm._tiled._COVARIANCE_CACHE_TILES", 1)
    packed = build(dense_weights_max=50, tile_size_m=0.1)
    packed.update(train)
    assert packed.tiled is not None and len(packed.tiled._packed) == len(packed.tiled.tiles) - 1
    estimate = packed.query(test.points_m[:1000])
    np.testing.assert_allclose(estimate.mean, expected.mean, atol=1e-9)
    np.testing.assert_allclose(estimate.std, expected.std, atol=1e-9)
    more = Observations(test.points_m[:300], test.targets[:300])
    whole.update(more)
    packed.update(more)  # a packed tile's precision comes back from its factor
    np.testing.assert_allclose(packed.query(test.points_m[1000:2000]).mean,
                               whole.query(test.points_m[1000:2000]).mean, atol=1e-8)


def test_a_repeated_grid_query_recomputes_only_the_tiles_that_fused_since(data, monkeypatch
                                                                          ) -> None:
    """A recorded snapshot costs in proportion to the tiles that changed (issue 36 §3)."""
    from hapticframe_bhm._dense import DenseBelief

    train, _ = data
    region = RegionConfig(x_min_m=0.0, x_max_m=3.0, y_min_m=0.0, y_max_m=2.0)
    bhm, reference = build(region=region), build(region=region)
    bhm.update(train)
    reference.update(train)
    first = bhm.probability_grid(0.02)
    calls: list[int] = []
    original = DenseBelief.grid_moments
    monkeypatch.setattr(DenseBelief, "grid_moments",
                        lambda self, qx, qy: calls.append(1) or original(self, qx, qy))
    again = bhm.probability_grid(0.02)
    assert not calls  # nothing fused: every tile's moments come from the last query
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    corner = Observations(np.array([[0.1, 0.1]]), np.array([1.0]))
    bhm.update(corner)
    reference.update(corner)
    fused = bhm.probability_grid(0.02)
    assert 0 < len(calls) < len(bhm.tiled.tiles)  # only the tiles the point reached
    for a, b in zip(fused, reference.probability_grid(0.02), strict=True):
        np.testing.assert_array_equal(a, b)  # the same as a map that never cached


def test_a_grid_query_leaves_the_cache_of_whole_beliefs_as_it_was(data, monkeypatch) -> None:
    """A snapshot reads every tile; it must not pack the tiles the run is fusing into (their
    covariances would be rebuilt on the next fuse: issue 36 §3)."""
    train, test = data
    monkeypatch.setattr("hapticframe_bhm._tiled._COVARIANCE_CACHE_TILES", 2)
    bhm = build(dense_weights_max=50, tile_size_m=0.1)
    bhm.update(train)
    tiled = bhm.tiled
    assert tiled is not None and len(tiled._packed) == len(tiled.tiles) - 2
    whole_before, packed_before = list(tiled._covariances), set(tiled._packed)
    grid = bhm.probability_grid(0.02)
    assert list(tiled._covariances) == whole_before and set(tiled._packed) == packed_before
    assert all(not hasattr(tiled.tiles[tile], "posterior") for tile in packed_before)
    reference = build(dense_weights_max=50, tile_size_m=0.1)
    reference.update(train)
    for a, b in zip(grid, reference.probability_grid(0.02), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-9)
    more = Observations(test.points_m[:300], test.targets[:300])
    bhm.update(more)
    reference.update(more)
    np.testing.assert_allclose(bhm.query(test.points_m[300:900]).mean,
                               reference.query(test.points_m[300:900]).mean, atol=1e-8)


def test_two_grids_asked_in_turn_are_both_kept(data, monkeypatch) -> None:
    """A recorded run's snapshot grid and its planner's grid alternate: neither recomputes
    the tiles that did not fuse (issue 36 §3)."""
    from hapticframe_bhm._dense import DenseBelief

    train, _ = data
    region = RegionConfig(x_min_m=0.0, x_max_m=3.0, y_min_m=0.0, y_max_m=2.0)
    bhm = build(region=region)
    bhm.update(train)
    first, second = bhm.probability_grid(0.02), bhm.probability_grid(0.03)
    calls: list[int] = []
    original = DenseBelief.grid_moments
    monkeypatch.setattr(DenseBelief, "grid_moments",
                        lambda self, qx, qy: calls.append(1) or original(self, qx, qy))
    for a, b in zip(first, bhm.probability_grid(0.02), strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(second, bhm.probability_grid(0.03), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not calls
    bhm.probability_grid(0.05)  # a third grid pushes out the oldest
    calls.clear()
    bhm.probability_grid(0.03)
    assert not calls
    bhm.probability_grid(0.02)
    assert calls
