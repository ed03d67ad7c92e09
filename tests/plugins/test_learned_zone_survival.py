"""The learned zone's ``background_likelihood: survival`` (issue 32 §5): a background
report clears the cells nearest the plate, and those it passed, at least as surely as the
nearest cell the calibration saw occupied."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe.kinds import LocatedMeasurement
from hapticframe_learned_zone import LearnedZoneConfig
from hapticframe_learned_zone._functional import survival_background
from tests.plugins.test_learned_zone import CLASSES, _approaches, _zone

FREE, JAMMING = np.eye(3)[0], np.eye(3)[1]


def _reference(background, total, p_free, marginal, strength):
    """One column, farthest cell last: the recursion written out cell by cell."""
    n = len(total)
    estimate, samples = [0.0] * n, [0.0] * n
    prior, prior_samples = marginal, 0.0
    for i in reversed(range(n)):
        estimate[i] = min((background[i] + strength * prior) / (total[i] + strength), prior)
        samples[i] = max(total[i], prior_samples)
        prior, prior_samples = estimate[i], samples[i]
    ratio = [min(np.log(e) - np.log(p), 0.0) for e, p in zip(estimate, p_free, strict=True)]
    return np.array(ratio), np.array(samples)


def test_survival_background_against_a_cell_by_cell_reference():
    # ahead -1, 0, 1, 2, 3 (cells); the object seen occupied from 1 on, free reported
    # with it 2 and 3 ahead, never 1 ahead: the search halted before.
    background = np.array([0.0, 0.0, 0.0, 6.0, 30.0])
    jamming = np.array([0.0, 0.0, 6.0, 8.0, 10.0])
    counts = np.column_stack([background, jamming, np.zeros(5)])
    p_free = np.full(5, 0.98)
    ratio, samples = survival_background(counts, p_free, 0.96, 4.0, (5, 1))
    ref_ratio, ref_samples = _reference(background, background + jamming, p_free, 0.96, 4.0)
    np.testing.assert_allclose(ratio, ref_ratio, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(samples, ref_samples)
    # never weaker nearer the plate; the cells it passed take the nearest seen cell's
    assert np.all(np.diff(ratio) >= 0.0)
    assert ratio[0] == ratio[1] == ratio[2] < -1.0 and samples[0] == 40.0
    # the same cell shrunk towards the class frequency says little
    shrunk = np.log((0.0 + 4.0 * 0.96) / (6.0 + 4.0)) - np.log(0.98)
    assert ratio[2] < shrunk - 0.5


def test_survival_columns_are_independent_and_never_raise_the_odds():
    rng = np.random.default_rng(4)
    counts = rng.integers(0, 20, size=(6 * 3, 3)).astype(np.float64)
    p_free = rng.uniform(0.5, 0.99, size=18)
    ratio, samples = survival_background(counts, p_free, 0.9, 4.0, (6, 3))
    assert np.all(ratio <= 0.0) and np.all(samples >= counts.sum(axis=1))
    grid = counts.reshape(6, 3, 3)
    for j in range(3):
        r, n = _reference(grid[:, j, 0], grid[:, j].sum(axis=1), p_free.reshape(6, 3)[:, j],
                          0.9, 4.0)
        np.testing.assert_allclose(ratio.reshape(6, 3)[:, j], r, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(samples.reshape(6, 3)[:, j], n)


def _pair():
    rec = _approaches(np.random.default_rng(3), 0.03)
    shrunk, survival = _zone(), _zone(background_likelihood="survival")
    shrunk.fit([rec])
    survival.fit([rec])
    return shrunk, survival


def test_a_background_report_clears_the_path_and_the_cells_nearest_the_plate():
    shrunk, survival = _pair()
    centre = int(np.argmin(np.abs(survival.aside_m)))
    behind = survival.ahead_m <= 0.0
    for depth in (0.044, 0.02, float("nan")):
        _, r0, _ = shrunk.cell_maps(FREE, depth)
        t1, r1, w1 = survival.cell_maps(FREE, depth)
        # the calibration never saw the plate's own path occupied: shrunk says nothing
        assert np.all(np.abs(r0[behind, centre]) < 0.2)
        assert np.all(r1[behind, centre] < -1.0) and np.all(w1[behind, centre] > 0.3)
        assert np.all(t1[behind, centre] < 0.3)
        # along the heading the evidence never weakens as the object nears (up to the
        # cells' own p(free | cell free), which differ by less than 0.01 in log)
        assert np.all(np.diff(r1[:, centre]) >= -0.01)
        assert np.all(r1 <= 0.0)


def test_survival_leaves_every_other_report_alone():
    shrunk, survival = _pair()
    for q in (JAMMING, np.eye(3)[2], np.array([0.7, 0.3, 0.0])):
        for depth in (0.044, float("nan")):
            for a, b in zip(shrunk.cell_maps(q, depth), survival.cell_maps(q, depth),
                            strict=True):
                np.testing.assert_array_equal(a, b)
    assert (shrunk.training_report()["reach_ahead_m"]
            == survival.training_report()["reach_ahead_m"])


def test_observed_background_reports_reach_the_path_behind_the_plate():
    shrunk, survival = _pair()
    report = LocatedMeasurement(np.array([0.0]), np.array([[0.3, 0.2]]), np.array([0.0]),
                                FREE[None, :], CLASSES, np.array([0.044]))
    a, b = shrunk.observe(report), survival.observe(report)
    on_path = np.abs(b.points_m[:, 1] - 0.2) < 1e-9
    passed = b.points_m[on_path & (b.points_m[:, 0] < 0.3)]
    assert len(passed) and np.all(b.targets[on_path & (b.points_m[:, 0] < 0.3)] < 0.3)
    # shrunk placed nothing on the path behind the plate
    assert not np.any((np.abs(a.points_m[:, 1] - 0.2) < 1e-9) & (a.points_m[:, 0] < 0.3))


def test_the_survival_model_round_trips(tmp_path):
    _, survival = _pair()
    survival.save(tmp_path)
    loaded = _zone(background_likelihood="survival", model_dir=str(tmp_path))
    for a, b in zip(survival.cell_maps(FREE, 0.03), loaded.cell_maps(FREE, 0.03), strict=True):
        np.testing.assert_array_equal(a, b)


def test_an_unknown_background_likelihood_is_refused():
    with pytest.raises(ValidationError, match="background_likelihood"):
        LearnedZoneConfig(background_likelihood="hazard")
