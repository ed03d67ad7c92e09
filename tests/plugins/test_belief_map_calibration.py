"""The belief map's Platt calibration ranks scattered observations the right way round.

Issue 16 §6: 3,000 uniformly scattered points with a little label noise are binned into
6.4 cm cells, where a free and a contact bin share each noisy cell. Splitting such a pair
across cross-validation folds makes every held-out bin's decision value point the other
way, and an unconstrained Platt sigmoid then fitted a positive slope: the map inverted
(AUC 0.006, P 1e-11 at the disc's centre, 0.87 far from it).
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe import Circle, Scene
from hapticframe.kinds import BuildContext, Observations
from hapticframe_belief_map import BeliefMap, BeliefMapConfig
from hapticframe_belief_map import _functional as fn

#: The kit's scene: an 8 cm disc at (0.40, 0.25) m in the thesis's 0.75 x 0.50 m region.
SCENE = Scene(objects=[Circle(center_m=(0.40, 0.25), radius_m=0.04)])
CENTRE = np.array([[0.40, 0.25]])


def scattered(n: int, seed: int, noise: float = 0.03) -> Observations:
    """``n`` uniform points of the region labelled by the disc, a share ``noise`` flipped."""
    rng = np.random.default_rng(seed)
    region = SCENE.region.to_region()
    points = np.column_stack([
        rng.uniform(region.x_min_m, region.x_max_m, n),
        rng.uniform(region.y_min_m, region.y_max_m, n),
    ])
    labels = SCENE.occupied(points)
    flip = rng.random(n) < noise
    return Observations(points, (labels ^ flip).astype(float))


def held_out(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Probe points: 300 uniform in the region and 100 inside the disc, with the truth."""
    rng = np.random.default_rng(seed)
    region = SCENE.region.to_region()
    uniform = np.column_stack([
        rng.uniform(region.x_min_m, region.x_max_m, 300),
        rng.uniform(region.y_min_m, region.y_max_m, 300),
    ])
    radius = 0.04 * np.sqrt(rng.uniform(0.0, 0.95, 100))
    angle = rng.uniform(0.0, 2 * np.pi, 100)
    inside = CENTRE + np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    points = np.vstack([uniform, inside])
    return points, SCENE.occupied(points)


def auc(score: np.ndarray, truth: np.ndarray) -> float:
    """Area under the ROC curve (Mann-Whitney, ties count one half)."""
    pos, neg = score[truth], score[~truth]
    greater = (pos[:, None] > neg[None, :]).sum()
    ties = (pos[:, None] == neg[None, :]).sum()
    return float((greater + 0.5 * ties) / (pos.size * neg.size))


def build_map(seed: int = 0, **config) -> BeliefMap:
    context = BuildContext(id="belief", rng=np.random.default_rng(seed), scene=SCENE)
    return BeliefMap(BeliefMapConfig(**config), context)


# --- the reproduction ------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "cell_m"), [(1000, 0.032), (3000, 0.064)])
@pytest.mark.parametrize("seed", [0, 1])
def test_scattered_points_rank_the_disc_above_free_ground(n: int, cell_m: float, seed: int) -> None:
    the_map = build_map()
    the_map.update(scattered(n, seed))
    assert the_map.fitted and the_map.cell_size_m == pytest.approx(cell_m)
    points, truth = held_out(seed + 100)
    mean = the_map.query(points).mean
    assert auc(mean, truth) >= 0.95
    assert the_map.query(CENTRE).mean[0] > 0.8
    assert mean[~truth].mean() < 0.15  # free ground reads free


def test_the_fitted_link_never_lowers_p_as_the_decision_value_rises() -> None:
    for n in (300, 1000, 3000):
        the_map = build_map()
        the_map.update(scattered(n, 2, noise=0.1))
        model = the_map._current.model
        assert model.slope >= 0.0
        decision = np.linspace(-5, 5, 101)
        assert np.all(np.diff(model.link(decision)) >= 0.0)


def test_few_contacts_in_one_fold_still_calibrate_on_whole_cells() -> None:
    """Contact observations that all hash to one fold leave no held-out contact: whole
    cells are held out instead, and the map still ranks the contact line first."""
    x_free = np.r_[np.linspace(0.0, 0.08, 100), np.linspace(0.12, 0.2, 100)]
    free = np.column_stack([x_free, np.zeros(200)])
    candidates = np.column_stack([np.linspace(0.09, 0.11, 400), np.full(400, 0.0004)])
    one_fold = candidates[fn.observation_folds(candidates, 3) == 1][::8][:6]
    points = np.vstack([free, one_fold])
    targets = np.r_[np.zeros(200), np.ones(len(one_fold))]
    the_map = build_map(unexplored_prior=None)
    the_map.update(Observations(points, targets))
    assert the_map.fitted and the_map._current.model.slope > 0
    probe = the_map.query([[0.10, 0.0], [0.02, 0.0], [0.18, 0.0]]).mean
    assert probe[0] > probe[1:].max()


# --- the calibration's parts -----------------------------------------------------------------


def test_platt_fit_recovers_a_sigmoid_and_never_inverts() -> None:
    rng = np.random.default_rng(0)
    decision = rng.normal(0.0, 2.0, 4000)
    labels = (rng.random(4000) < 1 / (1 + np.exp(-(1.5 * decision - 0.5)))).astype(np.int64)
    slope, intercept = fn.platt_fit(decision, labels, np.ones(4000))
    assert slope == pytest.approx(1.5, rel=0.1) and intercept == pytest.approx(-0.5, abs=0.15)
    # Weights count as repeated samples.
    half = slice(0, 2000)
    doubled = fn.platt_fit(
        np.concatenate([decision[half], decision[half]]),
        np.concatenate([labels[half], labels[half]]), np.ones(4000))
    weighted = fn.platt_fit(decision[half], labels[half], np.full(2000, 2.0))
    np.testing.assert_allclose(weighted, doubled, rtol=1e-4, atol=1e-6)
    # Labels that fall as the decision value rises: the slope stops at zero, and the
    # intercept is Platt's smoothed base rate (1/(w0 + 2) and (w1 + 1)/(w1 + 2) targets).
    slope, intercept = fn.platt_fit(decision, 1 - labels, np.ones(4000))
    assert slope == 0.0
    w1 = float((1 - labels).sum())
    expected = ((w1 + 1) / (w1 + 2) * w1 + (4000 - w1) / (4000 - w1 + 2)) / 4000
    assert 1 / (1 + np.exp(-intercept)) == pytest.approx(expected, rel=1e-4)
    # Huge decision values (a heavily weighted SVC) stay finite.
    slope, intercept = fn.platt_fit(1e6 * decision, labels, np.ones(4000))
    assert np.isfinite([slope, intercept]).all() and slope > 0
    # One decision value everywhere: no ranking, a flat link.
    assert fn.platt_fit(np.zeros(10), np.arange(10) % 2, np.ones(10))[0] == 0.0


def test_observation_folds_are_a_hash_of_the_position() -> None:
    points = np.random.default_rng(3).uniform(-1.0, 1.0, (6000, 2))
    folds = fn.observation_folds(points, 3)
    assert set(np.unique(folds)) == {0.0, 1.0, 2.0}
    assert np.bincount(folds.astype(int)).min() > 1800  # about a third each
    np.testing.assert_array_equal(fn.observation_folds(points[::-1], 3), folds[::-1])
    # A fingertip raked at a fixed step still visits every fold along its line.
    line = np.column_stack([0.1 + 0.002 * np.arange(300), np.full(300, 0.25)])
    assert np.bincount(fn.observation_folds(line, 3).astype(int)).min() > 70


def test_calibration_splits_hold_out_raw_observations() -> None:
    rng = np.random.default_rng(4)
    points = rng.uniform(0.0, 0.3, (2000, 2))
    targets = (rng.random(2000) < 0.3).astype(float)
    bins = fn.bin_observations(points, targets, np.ones(2000), 0.05, folds=3)
    splits = fn.calibration_splits(bins, 3, seed=0)
    assert len(splits) == 3
    for fold, (train, held) in enumerate(splits):
        # The held-out bins are one fold's observations; training merges the others per cell.
        np.testing.assert_array_equal(held.keys[:, 3], fold)
        expected = fn.observation_folds(points, 3) != fold
        assert train.weights.sum() == pytest.approx(expected.sum())
        assert len(train) == train.cells_and_classes
    assert sum(held.weights.sum() for _, held in splits) == pytest.approx(2000)


def test_folds_hold_whole_cells_and_leave_both_classes_to_train_on() -> None:
    rng = np.random.default_rng(1)
    for trial in range(200):
        cells = rng.integers(0, 6, (rng.integers(4, 30), 2)).astype(float)
        classes = rng.integers(0, 2, len(cells)).astype(float)
        keys = np.unique(np.column_stack([cells, classes]), axis=0)
        labels = keys[:, 2].astype(np.int64)
        groups = np.unique(keys[:, :2], axis=0, return_inverse=True)[1].ravel()
        contact_cells = np.unique(groups[labels == 1]).size
        free_cells = np.unique(groups[labels == 0]).size
        if min(contact_cells, free_cells) < 2:
            with pytest.raises(ValueError):
                fn.cell_folds(keys, 3, seed=trial)
            continue
        folds = fn.cell_folds(keys, 3, seed=trial)
        assert folds.shape == (len(keys),)
        assert np.unique(folds).size == min(3, contact_cells, free_cells)
        for k in np.unique(folds):
            held, train = folds == k, folds != k
            # A cell's free and contact bins are held out together...
            assert not set(groups[held]) & set(groups[train])
            # ...and every training set still holds both classes.
            assert set(labels[train]) == {0, 1}
        np.testing.assert_array_equal(folds, fn.cell_folds(keys, 3, seed=trial))


# --- the conformance kit's scattered-points check --------------------------------------------


class _Inverted(BeliefMap):
    """The belief map read upside down: what the check must refuse."""

    def query(self, points_m):  # type: ignore[no-untyped-def]
        estimate = super().query(points_m)
        return type(estimate)(1.0 - estimate.mean, estimate.std)


def test_the_kit_ranks_the_belief_map_and_refuses_an_inverted_map() -> None:
    from hapticframe import MapSpec
    from hapticframe.testing import CheckFailure
    from hapticframe.testing._spatial import check_map_ranks_scattered_points
    from hapticframe_belief_map import plugin

    (spec,) = plugin.hapticframe_maps()
    check_map_ranks_scattered_points(spec)
    inverted = MapSpec(
        "inverted-belief", "x", BeliefMapConfig, f"{__name__}:_Inverted", requires=("sklearn",))
    with pytest.raises(CheckFailure, match=r"AUC 0\.\d+ \(below 0.5: the map is inverted\)"):
        check_map_ranks_scattered_points(inverted)
