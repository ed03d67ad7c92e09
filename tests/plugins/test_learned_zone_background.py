"""The learned zone's ``background_evidence``: a placed report of the background class
carries the evidence of the fitted samples of the travel it stands for (issue 32 §5)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe.kinds import LocatedMeasurement
from hapticframe_learned_zone import LearnedZoneConfig
from hapticframe_learned_zone._functional import observation_weights
from tests.plugins.test_learned_zone import CLASSES, _approaches, _zone

FREE, JAMMING = np.eye(3)[0], np.eye(3)[1]


def _fitted(**config):
    zone = _zone(**config)
    zone.fit([_approaches(np.random.default_rng(3), 0.03)])
    return zone


def test_per_travel_scales_a_free_report_by_the_samples_between_placed_reports():
    sample, travel = _fitted(), _fitted(background_evidence="per-travel")
    # defaults: one report placed per 2 cm, one sample fitted per 5 mm
    assert sample.background_samples() == 1.0
    assert travel.background_samples() == pytest.approx(4.0)
    for depth in (0.044, 0.02, float("nan")):
        _, r1, _ = sample.cell_maps(FREE, depth)
        t4, r4, w4 = travel.cell_maps(FREE, depth)
        np.testing.assert_allclose(r4, 4.0 * r1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(t4, 1.0 / (1.0 + np.exp(-r4)), rtol=0, atol=1e-12)
        expected = observation_weights(r4.ravel(), travel.occupied_samples[-1],
                                       travel.config.prior_strength,
                                       travel.config.full_weight_log_ratio)
        np.testing.assert_allclose(w4.ravel(), expected, rtol=0, atol=1e-12)
    # the free report clears harder: lower targets where it said anything at all
    t1, r1, _ = sample.cell_maps(FREE, 0.044)
    t4, _, _ = travel.cell_maps(FREE, 0.044)
    said = r1 < -0.05
    assert said.any() and np.all(t4[said] < t1[said])


def test_per_travel_leaves_other_classes_alone():
    sample, travel = _fitted(), _fitted(background_evidence="per-travel")
    for q in (JAMMING, np.eye(3)[2], np.array([0.3, 0.7, 0.0])):
        for a, b in zip(sample.cell_maps(q, 0.03), travel.cell_maps(q, 0.03), strict=True):
            np.testing.assert_array_equal(a, b)
    assert (sample.training_report()["reach_ahead_m"]
            == travel.training_report()["reach_ahead_m"])


@pytest.mark.parametrize(("spacing", "fit", "expected"),
                         [(0.02, 0.005, 4.0), (0.01, 0.005, 2.0), (0.002, 0.005, 1.0),
                          (0.0, 0.005, 1.0)])
def test_background_samples_follow_the_two_spacings(spacing, fit, expected):
    zone = _zone(background_evidence="per-travel", observation_spacing_m=spacing,
                 fit_spacing_m=fit)
    assert zone.background_samples() == pytest.approx(expected)


def test_observed_free_reports_carry_the_scaled_evidence():
    sample, travel = _fitted(), _fitted(background_evidence="per-travel")
    report = LocatedMeasurement(np.array([0.0]), np.array([[0.3, 0.2]]), np.array([0.0]),
                                FREE[None, :], CLASSES, np.array([0.044]))
    a, b = sample.observe(report), travel.observe(report)
    # more cells pass min_log_ratio, and every target is lower or equal
    assert len(b.targets) >= len(a.targets) and b.targets.min() < a.targets.min()
    assert b.weights.sum() > a.weights.sum()


def test_an_unknown_background_evidence_is_refused():
    with pytest.raises(ValidationError, match="background_evidence"):
        LearnedZoneConfig(background_evidence="per-metre")
