"""Plate-drag geometry and force pieces of the sandbox against the thesis's numbers.

The failure-zone mechanics the sandbox shares with the sensor model (Arthur angle, rupture
distance, side-crescent angle) are tested in test_granular_mechanics.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe import Circle, Scene
from hapticframe_sandbox import _functional as F


def test_sector_points_span_radius_and_half_angle():
    points, radii, angles = F.sector_ray_points((0.1, 0.2), 0.3, 0.05, math.radians(50), 11, 5)
    assert points.shape == (5, 11, 2)
    assert radii[0] == 0.0 and radii[-1] == pytest.approx(0.05)
    np.testing.assert_allclose(angles, 0.3 + np.radians([-50, -25, 0, 25, 50]))
    dist = np.linalg.norm(points - np.array([0.1, 0.2]), axis=-1)
    np.testing.assert_allclose(dist, np.broadcast_to(radii, (5, 11)), atol=1e-15)
    rel = points[:, -1] - np.array([0.1, 0.2])
    np.testing.assert_allclose(np.arctan2(rel[:, 1], rel[:, 0]), angles, atol=1e-12)


def test_first_hit_distance_matches_analytic_ray_circle_intersection():
    centre, radius = np.array([0.10, 0.02]), 0.04
    scene = Scene(objects=[Circle(center_m=tuple(centre), radius_m=radius)])
    angles = np.radians([-40.0, -10.0, 0.0, 11.3, 30.0, 80.0])
    radii = np.linspace(0.0, 0.12, 40)
    hits = F.first_hit_distances((0.0, 0.0), angles, radii, scene.occupied)
    for angle, hit in zip(angles, hits, strict=True):
        u = np.array([math.cos(angle), math.sin(angle)])
        # |t u - c|² = R²  →  t = u·c − sqrt((u·c)² − |c|² + R²)
        b = u @ centre
        disc = b * b - centre @ centre + radius * radius
        t = b - math.sqrt(disc) if disc >= 0 else math.inf
        if t > radii[-1]:
            t = math.inf
        if math.isinf(t):
            assert math.isinf(hit)
        else:
            assert hit == pytest.approx(t, abs=1e-5)
    # Some rays must hit and some miss for this check to mean anything.
    assert np.isfinite(hits).any() and np.isinf(hits).any()


def test_first_hit_distance_is_zero_inside_an_object():
    scene = Scene(objects=[Circle(center_m=(0.0, 0.0), radius_m=0.05)])
    hits = F.first_hit_distances((0.01, 0.0), np.zeros(3), np.linspace(0, 0.1, 10), scene.occupied)
    np.testing.assert_array_equal(hits, 0.0)


def test_plate_edge_points_are_perpendicular_to_motion():
    pts = F.plate_edge_points((1.0, 2.0), math.pi / 2, 0.02, n=5)
    np.testing.assert_allclose(pts[:, 1], 2.0, atol=1e-15)
    np.testing.assert_allclose(
        pts[:, 0], 1.0 + np.array([0.01, 0.005, 0.0, -0.005, -0.01]), atol=1e-15
    )


def test_free_drag_grows_with_depth_squared_and_is_fig_3_6_sized():
    c = 7750.0
    assert 10.0 <= F.free_drag_n(0.044, c) <= 20.0
    assert F.free_drag_n(0.022, c) == pytest.approx(F.free_drag_n(0.044, c) / 4)
    np.testing.assert_allclose(F.free_drag_n(np.array([0.0, 0.01]), c), [0.0, 0.775])


def test_startup_and_shear_cycle_factors():
    np.testing.assert_allclose(F.startup_factor([0.0, 0.035, 0.07, 1.0], 0.07), [0, 0.5, 1, 1])
    assert F.startup_factor(0.01, 0.0) == 1.0
    phases = np.linspace(0, 1, 101)
    saw = F.shear_cycle_factor(phases, 0.2)
    assert saw[0] == pytest.approx(0.9) and saw[-1] == pytest.approx(1.1)
    assert np.all(np.diff(saw) > 0)  # the drag builds through a cycle
    assert saw.mean() == pytest.approx(1.0)


def test_jamming_force_grows_as_the_plate_approaches():
    r, d, gain = 0.07, 0.044, 1200.0
    s = np.array([np.inf, 0.2, r, 0.05, 0.03, 0.01, 0.0])
    f = F.jamming_force_n(s, r, gain, d, 1.5)
    assert f[0] == f[1] == f[2] == 0.0
    assert np.all(np.diff(f[2:]) > 0)
    assert f[-1] == pytest.approx(gain * d)
    # With an exponent above 1 the force *rate* grows too (convex in the approach distance).
    increments = np.diff(F.jamming_force_n(np.linspace(r, 0, 8), r, gain, d, 1.5))
    assert np.all(np.diff(increments) > 0)


def test_contact_force_is_a_spring_on_penetration():
    np.testing.assert_allclose(F.contact_force_n([-0.01, 0.0, 0.002], 3000.0), [0.0, 0.0, 6.0])


# --- plain-float paths of a robot step equal the array paths ---------------------------------


def test_scalar_factors_equal_the_array_factors():
    rng = np.random.default_rng(2)
    travelled = np.concatenate([rng.uniform(-0.1, 0.3, 200), [0.0, -0.0, 0.07, np.nan]])
    for rupture in (0.071, 0.0, -1.0):
        for s in travelled.tolist():
            scalar = F.startup_factor(s, rupture)
            assert type(scalar) is float
            array = F.startup_factor(np.array([s]), rupture)[0]
            assert scalar == array or (math.isnan(scalar) and math.isnan(array))
    phases, amplitudes = rng.uniform(-0.5, 1.5, 200).tolist(), rng.uniform(0, 1, 200).tolist()
    for phase, amplitude in zip(phases, amplitudes, strict=True):
        scalar = F.shear_cycle_factor(phase, amplitude)
        assert type(scalar) is float
        assert scalar == F.shear_cycle_factor(np.array([phase]), np.array(amplitude))[0]
    assert math.isnan(F.shear_cycle_factor(math.nan, 0.2))


def test_first_hits_with_kept_rays_equal_fresh_ones():
    rng = np.random.default_rng(4)
    scene = Scene(objects=[Circle(center_m=(0.3, 0.25), radius_m=0.04)])
    angles = 0.4 + np.linspace(-0.9, 0.9, 9)
    radii = np.linspace(0.0, 0.07, 15)
    directions = F.unit_vector(angles)
    kept = radii[None, :, None] * directions[:, None, :]
    hits = 0
    for position in rng.uniform((0.18, 0.13), (0.42, 0.37), (200, 2)):
        fresh = F.first_hit_distances(position, angles, radii, scene.occupied)
        reused = F.first_hit_distances(
            position, angles, radii, scene.occupied, directions=directions, ray_offsets=kept
        )
        np.testing.assert_array_equal(reused, fresh)
        hits += np.isfinite(fresh).any()
    assert hits > 20  # the bisection was exercised
    edge = F.plate_edge_points((0.1, 0.2), 0.7, 0.02)
    np.testing.assert_array_equal(edge, np.array([0.1, 0.2]) + F.plate_edge_offsets(0.7, 0.02))
