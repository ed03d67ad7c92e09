"""WAM kinematics (pure numpy) against an independent product of DH matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe_barrett._wam_kinematics import WAM4, WAM7, DHLink, SerialArm, Transmission


def _rot_z(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)


def _rot_x(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]], dtype=float)


def _trans(x: float, y: float, z: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, 3] = (x, y, z)
    return out


def reference_tip(rows, q, tool, base_xyz, yaw) -> np.ndarray:
    """Standard DH written out as elementary motions: Rz(θ) Tz(d) Tx(a) Rx(α)."""
    t = _trans(*base_xyz) @ _rot_z(yaw)
    for (a, alpha, d), theta in zip(rows, q, strict=True):
        t = t @ _rot_z(theta) @ _trans(0, 0, d) @ _trans(a, 0, 0) @ _rot_x(alpha)
    return (t @ np.array([*tool, 1.0]))[:3]


# libbarrett's wam4.conf, typed in again: (a, alpha, d).
WAM4_ROWS = [(0, -math.pi / 2, 0), (0, math.pi / 2, 0), (0.045, -math.pi / 2, 0.55),
             (-0.045, math.pi / 2, 0)]
WAM7_ROWS = [*WAM4_ROWS, (0, -math.pi / 2, 0.3), (0, math.pi / 2, 0), (0, -math.pi / 2, 0.0609)]
BASE = (0.375, -0.25, 0.30)
YAW = math.pi / 2


@pytest.mark.parametrize(("preset", "rows"), [(WAM4, WAM4_ROWS), (WAM7, WAM7_ROWS)])
def test_forward_kinematics_match_the_reference(preset, rows) -> None:
    arm = SerialArm(preset.links, preset.tool_offset_m, preset.limits_rad, BASE, YAW)
    rng = np.random.default_rng(0)
    lo, hi = arm.limits[:, 0], arm.limits[:, 1]
    for q in rng.uniform(lo, hi, size=(25, arm.n)):
        np.testing.assert_allclose(arm.forward(q), reference_tip(rows, q, preset.tool_offset_m,
                                                                 BASE, YAW), atol=1e-12)
    # Zero posture: the arm stands straight up, the fingertip above the shoulder.
    np.testing.assert_allclose(arm.forward(np.zeros(arm.n)),
                               [BASE[0], BASE[1], BASE[2] + 0.55 + (0.36 + 0.15 if arm.n == 4
                                                                   else 0.3 + 0.0609 + 0.2)],
                               atol=1e-12)


def test_jacobian_matches_finite_differences() -> None:
    arm = SerialArm(WAM7.links, WAM7.tool_offset_m, WAM7.limits_rad, BASE, YAW)
    q = np.array(WAM7.ik_seed_rad) + 0.1
    jac, p, _, _ = arm.jacobian(q)
    eps = 1e-7
    numeric = np.column_stack([(arm.forward(q + eps * e) - arm.forward(q - eps * e)) / (2 * eps)
                               for e in np.eye(arm.n)])
    np.testing.assert_allclose(jac, numeric, atol=1e-7)
    np.testing.assert_allclose(p, arm.forward(q))


@pytest.mark.parametrize(("preset", "rows"), [(WAM4, WAM4_ROWS), (WAM7, WAM7_ROWS)])
def test_ik_round_trips_over_the_workspace(preset, rows) -> None:
    arm = SerialArm(preset.links, preset.tool_offset_m, preset.limits_rad, BASE, YAW,
                    preset.tool_axis)
    for x in np.linspace(0.0, 0.75, 4):
        for y in np.linspace(0.0, 0.5, 3):
            target = np.array([x, y, -0.044])
            result = arm.solve(target, preset.ik_seed_rad, min_iterations=30)
            assert result.ok, (x, y, result.error_m)
            assert arm.within_limits(result.q)
            # Checked by the independent product, not by the solver's own FK.
            np.testing.assert_allclose(
                reference_tip(rows, result.q, preset.tool_offset_m, BASE, YAW), target,
                atol=2e-5)
            # Elbow up, tool roughly down (the null-space preference).
            axis = arm.frames(result.q)[-1][:3, :3] @ preset.tool_axis
            assert axis[2] < -0.7
            assert arm.link_points(result.q)[1:-1, 2].min() > 0.1


def test_a_line_is_solved_point_by_point_and_stays_smooth() -> None:
    arm = SerialArm(WAM4.links, WAM4.tool_offset_m, WAM4.limits_rad, BASE, YAW)
    points = np.column_stack([np.linspace(0.05, 0.7, 131), np.full(131, 0.25),
                              np.full(131, -0.03)])
    first = arm.solve(points[0], WAM4.ik_seed_rad, min_iterations=30)
    q, errors = arm.solve_line(points, first.q)
    assert errors.max() < 1e-5
    assert np.abs(np.diff(q, axis=0)).max() < 0.02  # 5 mm apart: no branch jumps
    tips = np.array([reference_tip(WAM4_ROWS, qi, WAM4.tool_offset_m, BASE, YAW) for qi in q])
    np.testing.assert_allclose(tips, points, atol=2e-5)


def test_an_unreachable_point_does_not_converge() -> None:
    arm = SerialArm(WAM4.links, WAM4.tool_offset_m, WAM4.limits_rad, BASE, YAW)
    result = arm.solve([3.0, 0.0, 0.0], WAM4.ik_seed_rad)
    assert not result.ok and result.error_m > 1.0


def test_transmission_counts_round_trip() -> None:
    tr = Transmission(WAM4.j2mp, 4096)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    # J1: 42 motor turns per joint turn, reversed: -42 rad of motor per rad.
    assert tr.counts(q).tolist() == [round(-42 * 4096 / (2 * math.pi)), 0, 0, 0]
    # J2 and J3 share motors 2 and 3 (the differential).
    assert np.count_nonzero(tr.counts([0, 0.5, 0, 0])) == 2
    rng = np.random.default_rng(1)
    for qi in rng.uniform(-2, 2, size=(20, 4)):
        np.testing.assert_allclose(tr.joints(tr.counts(qi)), qi, atol=5e-4)
    with pytest.raises(ValueError, match="invertible"):
        Transmission(np.zeros((4, 4)), 4096)
    with pytest.raises(ValueError, match="positive"):
        Transmission(WAM4.j2mp, [4096, 0, 4096, 4096])


def test_limits_and_links_are_reported() -> None:
    arm = SerialArm([DHLink(0.0, 0.0, 0.0), DHLink(0.5, 0.0, 0.0)], (0.5, 0.0, 0.0),
                    [(-1.0, 1.0), (-2.0, 2.0)])
    assert arm.within_limits([[0.0, 0.0], [1.5, 0.0]]).tolist() == [True, False]
    expected = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(arm.link_points([0.0, 0.0]), expected)
    with pytest.raises(ValueError, match="limits"):
        SerialArm(arm.links, (0, 0, 0), [(-1.0, 1.0)])
