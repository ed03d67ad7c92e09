"""Outline, centroid and Hausdorff helpers."""

import numpy as np
import pytest

from hapticframe import Circle, Ellipse, Polygon, Scene
from hapticframe.geometry import (
    blob_centroid,
    directed_hausdorff_both,
    level_outlines,
    main_outline,
    sample_grid,
)


def _disc_field(cx, cy, r, spacing=0.005):
    xs, ys, pts = sample_grid((0, 0.75, 0, 0.5), spacing)
    d = np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)
    return xs, ys, (1 / (1 + np.exp((d - r) / 0.004))).reshape(len(ys), len(xs))


def test_outline_of_a_disc_matches_the_disc():
    xs, ys, v = _disc_field(0.3, 0.2, 0.04)
    outline = main_outline(xs, ys, v, 0.5)
    truth = Circle(center_m=(0.3, 0.2), radius_m=0.04).outline(400)
    a, b = directed_hausdorff_both(outline, truth)
    assert a < 0.004 and b < 0.004
    assert np.allclose(blob_centroid(xs, ys, v, 0.5), [0.3, 0.2], atol=1e-3)


def test_object_at_the_edge_still_gets_a_closed_outline():
    xs, ys, v = _disc_field(0.0, 0.25, 0.05)
    lines = level_outlines(xs, ys, v, 0.6)
    assert lines and lines[0][:, 0].min() >= 0.0
    centroid = blob_centroid(xs, ys, v, 0.6)
    assert 0.0 < centroid[0] < 0.04


def test_nothing_above_level_gives_none():
    xs, ys, _ = sample_grid((0, 1, 0, 1), 0.1)
    flat = np.full((len(ys), len(xs)), 0.3)
    assert level_outlines(xs, ys, flat, 0.6) == []
    assert blob_centroid(xs, ys, flat, 0.6) is None
    assert main_outline(xs, ys, flat, 0.6) is None


def test_heaviest_or_nearest_blob_is_chosen():
    xs, ys, big = _disc_field(0.2, 0.2, 0.05)
    _, _, small = _disc_field(0.6, 0.3, 0.02)
    field = np.maximum(big, small)
    assert np.allclose(blob_centroid(xs, ys, field, 0.6), [0.2, 0.2], atol=2e-3)
    assert np.allclose(blob_centroid(xs, ys, field, 0.6, near_m=(0.6, 0.3)), [0.6, 0.3], atol=2e-3)


def test_input_validation():
    with pytest.raises(ValueError, match="shape"):
        blob_centroid([0, 1], [0, 1, 2], np.zeros((2, 2)), 0.5)
    with pytest.raises(ValueError, match="NaN"):
        blob_centroid([0, 1], [0, 1], np.full((2, 2), np.nan), 0.5)
    with pytest.raises(ValueError):
        directed_hausdorff_both(np.empty((0, 2)), [[0, 0]])
    with pytest.raises(ValueError):
        sample_grid((0, 1, 0, 1), 0.0)


def test_scene_shapes_contain_and_centroid():
    ellipse = Ellipse(center_m=(0.3, 0.2), semi_axes_m=(0.045, 0.025), orientation_deg=90)
    assert ellipse.contains([[0.3, 0.24]]).all() and not ellipse.contains([[0.34, 0.2]]).any()
    square = Polygon(center_m=(0.5, 0.5),
                     vertices_m=[(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)])
    assert square.contains([[0.55, 0.45]]).all() and not square.contains([[0.65, 0.5]]).any()
    assert np.allclose(square.centroid_m, [0.5, 0.5], atol=1e-9)
    scene = Scene(objects=[ellipse, square])
    assert scene.occupied([[0.3, 0.2], [0.0, 0.0]]).tolist() == [True, False]
    assert scene.material.friction_angle_deg == 42.0 and scene.material.dilation_angle_deg == 12.0


def test_rotations_agree_with_scipy():
    from scipy.spatial.transform import Rotation

    from hapticframe.geometry import (
        rotation_matrix_from_rpy_deg,
        rotation_matrix_from_wxyz,
        wxyz_from_rotation_matrix,
    )

    rng = np.random.default_rng(4)
    half_turns = [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 2.0], [0.0, 0.6, 0.8, 0.0]]
    for q in [*rng.standard_normal((50, 4)), *half_turns]:
        q = np.asarray(q)
        reference = Rotation.from_quat(np.roll(q, -1))  # scipy is scalar last
        matrix = rotation_matrix_from_wxyz(q)
        np.testing.assert_allclose(matrix, reference.as_matrix(), atol=1e-12)
        back = wxyz_from_rotation_matrix(matrix)
        assert back[0] >= 0
        np.testing.assert_allclose(rotation_matrix_from_wxyz(back), matrix, atol=1e-12)
    for rpy in rng.uniform(-180, 180, (50, 3)):
        reference = Rotation.from_euler("xyz", rpy, degrees=True)  # fixed axes: Rz Ry Rx
        np.testing.assert_allclose(rotation_matrix_from_rpy_deg(rpy), reference.as_matrix(),
                                   atol=1e-12)


@pytest.mark.parametrize("q", [[0.0, 0.0, 0.0, 0.0], [1.0, np.nan, 0.0, 0.0], [1.0, 0.0, 0.0]])
def test_a_quaternion_that_is_no_rotation_is_refused(q):
    from hapticframe.geometry import rotation_matrix_from_wxyz

    with pytest.raises(ValueError, match="quaternion"):
        rotation_matrix_from_wxyz(q)
