"""Fitting Eq. 3.10 (m_e, R, ε) from free motions: recovery, signs, ill-conditioning, NaN."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hapticframe.geometry import rotation_matrix_from_wxyz
from hapticframe_force_observer import (
    ExcitationWarning,
    ObserverFit,
    apply_force_observer,
    fit_force_observer,
)
from hapticframe_force_observer._functional import _procrustes, rotation_angle_rad

G = 9.80665
MASS_KG = 0.8
R_TRUE = rotation_matrix_from_wxyz([0.97, 0.12, -0.18, 0.10])  # about 28° of misalignment
BIAS_N = np.array([1.5, -0.7, 2.0])


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    return rotation_matrix_from_wxyz(rng.standard_normal(4))


def free_motions(
    rng: np.random.Generator, n: int = 3000, orientations: int = 8, accel_std: float = 2.0
) -> np.ndarray:
    """IMU specific force (gravity included) of random accelerations at random orientations.

    The IMU's world orientation is constant within each of ``orientations`` stretches:
    a_imu = R_wiᵀ (a_w + g ẑ).
    """
    parts = []
    for size in np.diff(np.linspace(0, n, orientations + 1).astype(int)):
        r_wi = random_rotation(rng)
        specific = rng.normal(0.0, accel_std, (size, 3)) + [0.0, 0.0, G]
        parts.append(specific @ r_wi)  # rows: (R_wiᵀ s)ᵀ = sᵀ R_wi
    return np.concatenate(parts)


def sensed(accel: np.ndarray, mass: float, rotation: np.ndarray, bias: np.ndarray,
           rng: np.random.Generator, noise_n: float = 0.3) -> np.ndarray:
    return mass * accel @ rotation.T + bias + rng.normal(0.0, noise_n, accel.shape)


def angle_between_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(rotation_angle_rad(a.T @ b)))


def test_recovers_known_parameters_with_noise():
    rng = np.random.default_rng(1)
    a = free_motions(rng)
    f = sensed(a, MASS_KG, R_TRUE, BIAS_N, rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)
        fit = fit_force_observer(f, a)
    assert fit.mass_kg == pytest.approx(MASS_KG, abs=0.005)
    assert angle_between_deg(fit.rotation, R_TRUE) < 0.3
    np.testing.assert_allclose(fit.bias_n, BIAS_N, atol=0.05)
    # The residual is the sensor noise alone: 0.3 N per axis → 0.52 N as a 3-D norm.
    assert fit.residual_rms_n == pytest.approx(0.3 * np.sqrt(3), rel=0.05)
    assert fit.raw_rms_n > 5.0 and fit.excited_directions == 3 and fit.warning is None
    assert fit.samples == len(a) and fit.rows_dropped == 0
    np.testing.assert_allclose(np.linalg.det(fit.rotation), 1.0, atol=1e-12)
    assert np.all(fit.rotation_std_deg < 0.3)
    # Applying the fit to the recording leaves only the noise.
    f_env = apply_force_observer(f, a, fit)
    assert np.sqrt(np.mean(np.sum(f_env**2, axis=1))) == pytest.approx(fit.residual_rms_n)


def test_noise_free_recovery_is_exact():
    rng = np.random.default_rng(2)
    a = free_motions(rng, n=300)
    fit = fit_force_observer(sensed(a, MASS_KG, R_TRUE, BIAS_N, rng, noise_n=0.0), a)
    assert fit.mass_kg == pytest.approx(MASS_KG, abs=1e-10)
    np.testing.assert_allclose(fit.rotation, R_TRUE, atol=1e-10)
    np.testing.assert_allclose(fit.bias_n, BIAS_N, atol=1e-9)


def test_identity_case():
    rng = np.random.default_rng(3)
    a = free_motions(rng)
    fit = fit_force_observer(sensed(a, MASS_KG, np.eye(3), np.zeros(3), rng), a)
    assert np.degrees(rotation_angle_rad(fit.rotation)) < 0.3
    assert fit.mass_kg == pytest.approx(MASS_KG, abs=0.005)
    np.testing.assert_allclose(fit.bias_n, 0.0, atol=0.05)


def test_negative_gain_is_fitted_with_a_proper_rotation():
    rng = np.random.default_rng(4)
    a = free_motions(rng)
    f = sensed(a, -MASS_KG, R_TRUE, BIAS_N, rng)
    fit = fit_force_observer(f, a)
    assert fit.mass_kg == pytest.approx(-MASS_KG, abs=0.005)
    assert angle_between_deg(fit.rotation, R_TRUE) < 0.3
    np.testing.assert_allclose(fit.bias_n, BIAS_N, atol=0.05)
    # Forcing a positive gain would need an improper R: the best proper one fits far worse.
    r_pos = _procrustes((a - a.mean(0)).T @ (f - f.mean(0)))
    m_pos = np.trace(r_pos @ (a - a.mean(0)).T @ (f - f.mean(0))) / np.sum((a - a.mean(0)) ** 2)
    worse = f - m_pos * a @ r_pos.T
    assert np.sqrt(np.mean(np.sum((worse - worse.mean(0)) ** 2, 1))) > 3 * fit.residual_rms_n


def test_tilting_about_one_axis_warns_and_keeps_r_bounded():
    """Small tilts about x: gravity varies along y only; the twist about y is unseen."""
    rng = np.random.default_rng(0)
    tilt = np.radians(rng.uniform(-6.0, 6.0, 2000))
    true = np.stack([np.zeros_like(tilt), G * np.sin(tilt), G * np.cos(tilt)], axis=1)
    f = sensed(true, MASS_KG, np.eye(3), BIAS_N, rng, noise_n=0.5)
    a = true + rng.normal(0.0, 0.02, true.shape)  # the IMU's own noise
    with pytest.warns(ExcitationWarning, match="not identifiable") as record:
        fit = fit_force_observer(f, a)
    message = str(record[0].message)
    assert "one direction only, (+0.00, +1.00, +0.00) in the IMU frame" in message
    assert fit.excited_directions == 1 and fit.warning == message
    assert np.isinf(fit.rotation_std_deg[0])
    # The unseen rotation about y stays at the identity: R is within noise of I.
    assert np.degrees(rotation_angle_rad(fit.rotation)) < 4.0
    assert fit.mass_kg == pytest.approx(MASS_KG, rel=0.05)
    # Unconstrained Procrustes on the same data turns wildly about the unseen direction.
    naive = _procrustes((a - a.mean(0)).T @ (f - f.mean(0)))
    assert np.degrees(rotation_angle_rad(naive)) > 20.0


def test_motions_along_one_axis_give_the_smallest_consistent_rotation():
    rng = np.random.default_rng(6)
    a = np.zeros((1500, 3))
    a[:, 0] = rng.normal(0.0, 3.0, 1500)  # pushes along the IMU's x at a fixed orientation
    a[:, 2] = G
    f = sensed(a, MASS_KG, R_TRUE, BIAS_N, rng, noise_n=0.05)
    with pytest.warns(ExcitationWarning, match="one direction only"):
        fit = fit_force_observer(f, a)
    x = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(fit.rotation @ x, R_TRUE @ x, atol=2e-3)
    # Any rotation mapping x there is at least as large; the fit adds nothing about x.
    assert rotation_angle_rad(fit.rotation) <= rotation_angle_rad(R_TRUE) + 1e-3
    axis = np.array([fit.rotation[2, 1] - fit.rotation[1, 2], fit.rotation[0, 2] -
                     fit.rotation[2, 0], fit.rotation[1, 0] - fit.rotation[0, 1]])
    assert abs(axis @ x) < 1e-3 * np.linalg.norm(axis)  # its axis is perpendicular to x
    assert fit.mass_kg == pytest.approx(MASS_KG, abs=0.01)


def test_no_excitation_keeps_identity_and_zero_mass():
    rng = np.random.default_rng(7)
    a = np.tile([0.0, 0.0, G], (200, 1)) + rng.normal(0.0, 0.001, (200, 3))
    f = sensed(a, MASS_KG, R_TRUE, BIAS_N, rng)
    with pytest.warns(ExcitationWarning, match="neither m_e nor R"):
        fit = fit_force_observer(f, a)
    assert fit.mass_kg == 0.0 and fit.excited_directions == 0
    np.testing.assert_array_equal(fit.rotation, np.eye(3))
    np.testing.assert_allclose(fit.bias_n, f.mean(axis=0))


def test_nan_rows_are_left_out_of_the_fit_and_invalid_in_the_output():
    rng = np.random.default_rng(8)
    a = free_motions(rng, n=600)
    f = sensed(a, MASS_KG, R_TRUE, BIAS_N, rng)
    bad_f, bad_a = [3, 100, 101, 599], [0, 250]
    f_nan, a_nan = f.copy(), a.copy()
    f_nan[bad_f, 1] = np.nan
    a_nan[bad_a, 2] = np.inf
    fit = fit_force_observer(f_nan, a_nan)
    keep = np.ones(len(a), dtype=bool)
    keep[bad_f + bad_a] = False
    clean = fit_force_observer(f[keep], a[keep])
    assert fit.rows_dropped == 6 and fit.samples == keep.sum()
    assert fit.mass_kg == pytest.approx(clean.mass_kg, abs=1e-12)
    np.testing.assert_allclose(fit.rotation, clean.rotation, atol=1e-12)
    out = apply_force_observer(f_nan, a_nan, fit)
    np.testing.assert_array_equal(np.isnan(out).any(axis=1), ~keep)
    np.testing.assert_array_equal(np.isnan(out).all(axis=1), ~keep)
    assert out.dtype == np.float64


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="shape"):
        fit_force_observer(np.zeros((10, 2)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="differ in length"):
        fit_force_observer(np.zeros((10, 3)), np.zeros((9, 3)))
    with pytest.raises(ValueError, match="at least 3"):
        fit_force_observer(np.full((10, 3), np.nan), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="rotation"):
        ObserverFit(1.0, np.diag([1.0, 1.0, -1.0]), np.zeros(3))
    with pytest.raises(ValueError, match="bias_n"):
        ObserverFit(1.0, np.eye(3), np.array([0.0, np.nan, 0.0]))


def test_report_is_strict_json():
    import json

    rng = np.random.default_rng(9)
    a = np.zeros((100, 3))
    a[:, 0] = rng.normal(0.0, 1.0, 100)
    with pytest.warns(ExcitationWarning):
        fit = fit_force_observer(sensed(a, 1.0, np.eye(3), np.zeros(3), rng), a)
    report = json.loads(json.dumps(fit.report(), allow_nan=False))
    assert report["condition"] is None and report["rotation_std_deg"][0] is None
    assert report["excited_directions"] == 1
