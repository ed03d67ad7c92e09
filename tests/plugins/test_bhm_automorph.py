"""Automorphing kernels of the Bayesian Hilbert map (hapticframe_bhm._automorph, issue 19 §1)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import Scene
from hapticframe.kinds import BuildContext, Observations
from hapticframe_bench import labelled_points, roc_auc, two_object_scene
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_bhm._automorph import length_scale_levels


def build(seed: int = 0, scene: Scene | None = None, **config) -> BayesianHilbertMap:
    context = BuildContext(id="bhm", rng=np.random.default_rng(seed), scene=scene)
    return BayesianHilbertMap(BayesianHilbertMapConfig(**config), context)


def test_levels_are_log_spaced_and_hold_the_stationary_scale() -> None:
    levels = length_scale_levels(0.033, 0.5, 2.0, 7)
    assert levels[0] == pytest.approx(0.0165) and levels[-1] == pytest.approx(0.066)
    assert 0.033 in levels and np.all(np.diff(np.log(levels)) > 0)


def test_the_options_exclude_each_other() -> None:
    with pytest.raises(ValidationError, match="exclude each other"):
        BayesianHilbertMapConfig(automorphing_kernels=True, region_dependent_smoothing=True)
    with pytest.raises(ValidationError, match="automorphing_range"):
        BayesianHilbertMapConfig(automorphing_range=(1.5, 2.0))


def test_length_scales_are_learned_per_hinge_and_the_map_stays_accurate() -> None:
    rng = np.random.default_rng(1)
    scene = two_object_scene()
    train, test = labelled_points(scene, 1500, rng), labelled_points(scene, 5000, rng, 0.0)
    bhm = build(automorphing_kernels=True, automorphing_iterations=3)
    bhm.update(train)
    scales = bhm.length_scales
    levels = length_scale_levels(0.033, 0.5, 2.0, 7)
    assert np.all(np.isin(scales, levels)) and np.unique(scales).size >= 3
    assert bhm.refits == 1
    assert roc_auc(test.targets > 0.5, bhm.query(test.points_m).mean) > 0.99
    # A small batch is fused sequentially; doubling the data learns again.
    bhm.update(Observations(test.points_m[:100], test.targets[:100]))
    assert bhm.refits == 1 and np.array_equal(bhm.length_scales, scales)
    bhm.update(Observations(test.points_m[100:1600], test.targets[100:1600]))
    assert bhm.refits == 2
    xs, ys, mean, std = bhm.probability_grid(0.01)
    points = np.column_stack([g.ravel() for g in np.meshgrid(xs, ys, indexing="xy")])
    estimate = bhm.query(points[::5])
    np.testing.assert_allclose(estimate.mean, mean.ravel()[::5], atol=1e-9)
    np.testing.assert_allclose(estimate.std, std.ravel()[::5], atol=1e-9)
    bhm.reset()
    assert np.all(bhm.length_scales == 0.033)


def test_kernels_png_shows_the_learned_scales(tmp_path) -> None:
    pytest.importorskip("matplotlib")
    from hapticframe_bhm._plots import save_kernel_figure

    rng = np.random.default_rng(2)
    bhm = build(automorphing_kernels=True, automorphing_iterations=2)
    bhm.update(labelled_points(two_object_scene(), 800, rng))
    xs, ys, mean, _ = bhm.probability_grid(0.01)
    hxs, hys = bhm.hinge_axes
    hinges = np.column_stack([g.ravel() for g in np.meshgrid(hxs, hys, indexing="ij")])
    path = save_kernel_figure(tmp_path / "kernels.png", bhm.region, hinges,
                              bhm.length_scales.ravel(), xs, ys, mean)
    assert path.stat().st_size > 10_000
