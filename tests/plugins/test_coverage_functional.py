"""Tests of the pure coverage-planning functions (parallel lines, orders, angles, scores)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hapticframe_coverage import _functional as cf

BOX = (0.0, 0.75, 0.0, 0.50)


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from point p to each segment a[i]-b[i]."""
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=1) / np.sum(ab * ab, axis=1), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def test_lines_along_the_long_side() -> None:
    starts, ends = cf.parallel_lines(BOX, 0.0, 0.035)
    assert len(starts) == math.ceil(0.50 / 0.035) == 15
    np.testing.assert_allclose(starts[:, 0], 0.0)
    np.testing.assert_allclose(ends[:, 0], 0.75)
    ys = starts[:, 1]
    assert np.all(np.diff(ys) > 0) and np.all(np.diff(ys) <= 0.035 + 1e-12)
    assert ys[0] == pytest.approx(np.diff(ys)[0] / 2)  # half a strip from the border
    assert cf.longer_side_angle_deg(BOX) == 0.0
    assert cf.longer_side_angle_deg((0, 0.2, 0, 0.5)) == 90.0


def test_vertical_lines() -> None:
    starts, ends = cf.parallel_lines(BOX, 90.0, 0.05)
    assert len(starts) == 15
    np.testing.assert_allclose(starts[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(ends[:, 1], 0.5, atol=1e-12)
    np.testing.assert_allclose(starts[:, 0], ends[:, 0])


@settings(max_examples=60, deadline=None)
@given(
    angle=st.floats(0, 180, exclude_max=True),
    cx=st.floats(0.04, 0.71),
    cy=st.floats(0.04, 0.46),
)
def test_an_eight_cm_circle_cannot_be_missed(angle: float, cx: float, cy: float) -> None:
    starts, ends = cf.parallel_lines(BOX, angle, 0.035)
    for points in (starts, ends):
        assert np.all((points >= [0, 0]) & (points <= [0.75, 0.5]))
    directions = np.degrees(np.arctan2(*(ends - starts).T[::-1]))
    assert max(cf.angle_gap_deg(d, angle) for d in directions) < 1e-6
    crossing = segment_distance(np.array([cx, cy]), starts, ends) < 0.04
    assert crossing.sum() >= 2


def test_binary_search_order() -> None:
    assert cf.binary_search_order(0) == []
    assert cf.binary_search_order(1) == [0]
    assert cf.binary_search_order(7) == [3, 1, 5, 0, 2, 4, 6]
    order = cf.binary_search_order(15)
    assert order == [7, 3, 11, 1, 5, 9, 13, 0, 2, 4, 6, 8, 10, 12, 14]
    for n in range(1, 40):
        order = cf.binary_search_order(n)
        assert sorted(order) == list(range(n))
        # After the first 2^k - 1 lines no gap between visited lines (or the edges) is
        # wider than about n / 2^k.
        for k in range(1, int(math.log2(n)) + 1):
            seen = sorted(order[: 2**k - 1])
            gaps = np.diff([-1, *seen, n])
            assert gaps.max() <= n / 2 ** (k - 1) + 1


def test_angle_gap() -> None:
    assert cf.angle_gap_deg(10, 170) == pytest.approx(20)
    assert cf.angle_gap_deg(0, 180) == pytest.approx(0)
    assert cf.angle_gap_deg(45, 135) == pytest.approx(90)


def test_sweep_angle_keeps_its_distance() -> None:
    rng = np.random.default_rng(1)
    draws = [cf.sample_sweep_angle_deg(rng, [0.0]) for _ in range(300)]
    assert min(draws) >= 30 and max(draws) <= 150
    assert max(draws) - min(draws) > 100  # spread over the allowed range
    draws = [cf.sample_sweep_angle_deg(rng, [0.0, 90.0]) for _ in range(300)]
    assert all(cf.angle_gap_deg(d, 0) >= 30 and cf.angle_gap_deg(d, 90) >= 30 for d in draws)
    assert all(0 <= d < 180 for d in draws)


def test_sweep_angle_forgets_oldest_when_crowded() -> None:
    rng = np.random.default_rng(2)
    used = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0]  # no direction is 30 degrees from all
    for _ in range(50):
        a = cf.sample_sweep_angle_deg(rng, used)
        assert all(cf.angle_gap_deg(a, u) >= 30 - 1e-9 for u in used[2:])
    same = [cf.sample_sweep_angle_deg(np.random.default_rng(7), [12.0]) for _ in range(2)]
    assert same[0] == same[1]
    with pytest.raises(ValueError):
        cf.sample_sweep_angle_deg(rng, [], 90.0)


def test_shrink_bounds() -> None:
    new = cf.shrink_bounds(BOX, [0.3, 0.2], 0.75, BOX, 0.1)
    assert new[1] - new[0] == pytest.approx(0.5625)
    assert new[3] - new[2] == pytest.approx(0.375)
    assert ((new[0] + new[1]) / 2, (new[2] + new[3]) / 2) == pytest.approx((0.3, 0.2))
    corner = cf.shrink_bounds(BOX, [0.74, 0.01], 0.75, BOX, 0.1)
    assert corner[1] == pytest.approx(0.75) and corner[2] == pytest.approx(0.0)
    small = cf.shrink_bounds((0.2, 0.32, 0.2, 0.3), [0.25, 0.25], 0.75, BOX, 0.1)
    assert small[1] - small[0] == pytest.approx(0.1) and small[3] - small[2] == pytest.approx(0.1)
    with pytest.raises(ValueError):
        cf.shrink_bounds(BOX, [np.nan, 0.2], 0.75, BOX, 0.1)


def test_points_along() -> None:
    pts, idx = cf.points_along([[0, 0], [0, 0]], [[0.1, 0], [0, 0.05]], 0.01)
    assert np.count_nonzero(idx == 0) == 11 and np.count_nonzero(idx == 1) == 6
    np.testing.assert_allclose(pts[idx == 0][-1], [0.1, 0])
    empty, idx = cf.points_along(np.empty((0, 2)), np.empty((0, 2)), 0.01)
    assert empty.shape == (0, 2) and idx.size == 0


def test_line_scores_hand_computed() -> None:
    points = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.2]])
    idx = np.array([0, 0, 1])
    scores = cf.line_scores(
        [0.2, 0.8, 0.5], [0.1, 0.0, 0.4], points, idx, [0.0, 0.0], (1.0, 0.5, -1.0), 0.2, 2
    )
    expected0 = (0.2 + 0.05 - 0.0) + (0.8 + 0.0 - 0.25)
    expected1 = 0.5 + 0.2 - 1.0
    np.testing.assert_allclose(scores, [expected0, expected1])


def test_uncertainty_fraction() -> None:
    std = np.array([0.0, 0.05, 0.2, 0.4])
    assert cf.uncertainty_fraction(std, "uncertain-area", 0.15) == pytest.approx(0.5)
    assert cf.uncertainty_fraction(std, "mean-std", 0.15) == pytest.approx(0.1625 / 0.5)
    assert cf.uncertainty_fraction([], "mean-std", 0.1) == 1.0
    with pytest.raises(ValueError):
        cf.uncertainty_fraction([np.nan], "mean-std", 0.1)
    with pytest.raises(ValueError):
        cf.uncertainty_fraction([0.1], "median", 0.1)


# --- approach directions ------------------------------------------------------------------------


def test_largest_angular_gap() -> None:
    from hapticframe_coverage._functional import largest_angular_gap_deg

    assert largest_angular_gap_deg([]) == 360.0
    assert largest_angular_gap_deg([45.0]) == 360.0
    assert largest_angular_gap_deg([0.0, 180.0]) == 180.0
    assert largest_angular_gap_deg([350.0, 10.0, 100.0]) == pytest.approx(250.0)
    assert largest_angular_gap_deg([0.0, 90.0, 180.0, 270.0, 720.0]) == pytest.approx(90.0)
    with pytest.raises(ValueError):
        largest_angular_gap_deg([np.nan])


def test_bearing_gap_scores() -> None:
    from hapticframe_coverage._functional import bearing_gap_scores_deg

    np.testing.assert_allclose(bearing_gap_scores_deg([0.0, 90.0], []), [180.0, 180.0])
    np.testing.assert_allclose(
        bearing_gap_scores_deg([0.0, 90.0, 200.0, 355.0], [10.0, 180.0]), [10.0, 80.0, 20.0, 15.0]
    )


def test_allowed_sweep_mask_keeps_the_separation_and_forgets_the_oldest() -> None:
    from hapticframe_coverage._functional import allowed_sweep_mask

    candidates = np.arange(0.0, 360.0, 5.0)
    ok = allowed_sweep_mask(candidates, [0.0], 30.0)
    gaps = np.minimum(candidates % 180, 180 - candidates % 180)
    np.testing.assert_array_equal(ok, gaps >= 30 - 1e-9)
    # Six directions 30 degrees apart leave nothing: the oldest is forgotten.
    used = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0]
    ok = allowed_sweep_mask(candidates, used, 30.0)
    assert ok.any()
    assert not ok[candidates % 180 == 150.0].any()
    with pytest.raises(ValueError):
        allowed_sweep_mask(candidates, used, 95.0)


def test_ray_exit_distance() -> None:
    from hapticframe_coverage._functional import ray_exit_distance

    box = (0.0, 0.75, 0.0, 0.5)
    np.testing.assert_allclose(
        ray_exit_distance([0.25, 0.1], [0.0, 90.0, 180.0, 270.0], box), [0.5, 0.4, 0.25, 0.1]
    )
    assert ray_exit_distance([0.25, 0.1], [45.0], box)[0] == pytest.approx(0.4 * np.sqrt(2))
    np.testing.assert_allclose(ray_exit_distance([1.0, 1.0], [0.0, 90.0], box), 0.0)
