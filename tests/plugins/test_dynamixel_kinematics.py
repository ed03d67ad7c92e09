"""Kinematics of the ``dynamixel`` robot's mechanisms (pure numpy): the planar two-link arm's
analytic inverse against an independent reference, its edge cases, the whole-line checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe_dynamixel._kinematics import (
    Axis,
    Gantry,
    Joint,
    TwoLink,
    arm_forward,
    arm_inverse,
    arm_jacobian,
    line_problem,
    segment_distances,
)

L1, L2 = 0.4, 0.3
BASE = np.array([0.1, -0.2])
PULSE_RAD = 2 * math.pi / 4096


def reachable_points(rng: np.random.Generator, n: int, l1: float = L1, l2: float = L2,
                     base: np.ndarray = BASE) -> np.ndarray:
    """Points uniformly in angle and radius inside the annulus (boundaries excluded)."""
    inner, outer = abs(l1 - l2), l1 + l2
    r = rng.uniform(inner + 1e-6, outer - 1e-6, n)
    phi = rng.uniform(-math.pi, math.pi, n)
    return base + np.column_stack([r * np.cos(phi), r * np.sin(phi)])


def elbow_of(angles: np.ndarray, l1: float = L1, base: np.ndarray = BASE) -> np.ndarray:
    # Composed separately from arm_forward: the elbow from the shoulder angle alone.
    return base + l1 * np.column_stack([np.cos(angles[:, 0]), np.sin(angles[:, 0])])


@pytest.mark.parametrize("elbow", ["right", "left"])
def test_forward_of_inverse_is_the_point_on_both_branches(elbow: str) -> None:
    rng = np.random.default_rng(15)
    points = reachable_points(rng, 2000)
    angles = arm_inverse(points, L1, L2, BASE, elbow)
    np.testing.assert_allclose(arm_forward(angles, L1, L2, BASE), points, atol=1e-12)
    # The independent reference: an elbow at l1 from the shoulder and l2 from the fingertip.
    elbows = elbow_of(angles)
    np.testing.assert_allclose(np.linalg.norm(elbows - BASE, axis=1), L1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(points - elbows, axis=1), L2, atol=1e-12)
    # The branch: the elbow lies to the right (clockwise) of shoulder → fingertip, or left.
    to_tip, to_elbow = points - BASE, elbows - BASE
    cross = to_tip[:, 0] * to_elbow[:, 1] - to_tip[:, 1] * to_elbow[:, 0]
    sign = -1.0 if elbow == "right" else 1.0
    assert np.all(sign * cross > 0)
    assert np.all(angles[:, 1] * -sign >= 0)  # right: θ2 ≥ 0


def test_inverse_of_forward_recovers_the_angles_of_its_branch() -> None:
    rng = np.random.default_rng(7)
    angles = np.column_stack([rng.uniform(-math.pi, math.pi, 500),
                              rng.uniform(0.01, math.pi - 0.01, 500)])
    for sign, elbow in ((1.0, "right"), (-1.0, "left")):
        q = angles * [1.0, sign]
        back = arm_inverse(arm_forward(q, L1, L2, BASE), L1, L2, BASE, elbow)
        wrapped = np.angle(np.exp(1j * (back - q)))  # equal up to whole turns
        np.testing.assert_allclose(wrapped, 0.0, atol=1e-9)


def test_edge_cases_stretched_folded_and_refusals() -> None:
    # Fully stretched along a direction: the elbow straight, the arm pointing there.
    direction = np.array([math.cos(0.3), math.sin(0.3)])
    stretched = BASE + (L1 + L2) * direction
    angles = arm_inverse(stretched, L1, L2, BASE)
    assert angles[1] == pytest.approx(0.0, abs=1e-6) and angles[0] == pytest.approx(0.3)
    np.testing.assert_allclose(arm_forward(angles, L1, L2, BASE), stretched, atol=1e-12)
    # On the inner boundary the arm folds back (θ2 = ±π).
    inner = BASE + (L1 - L2) * direction
    angles = arm_inverse(inner, L1, L2, BASE)
    assert abs(angles[1]) == pytest.approx(math.pi)
    np.testing.assert_allclose(arm_forward(angles, L1, L2, BASE), inner, atol=1e-12)
    # Equal links reach the shoulder itself, folded: finite angles that land there.
    at_base = arm_inverse(BASE, 0.3, 0.3, BASE)
    assert np.all(np.isfinite(at_base))
    np.testing.assert_allclose(arm_forward(at_base, 0.3, 0.3, BASE), BASE, atol=1e-12)
    # Beyond reach, inside the hole, at the shoulder of unequal links, NaN: named errors.
    with pytest.raises(ValueError, match=r"\(0\.9, -0\.2\) is 0\.8 m from the shoulder"):
        arm_inverse([[0.2, 0.1], [0.9, -0.2]], L1, L2, BASE)
    with pytest.raises(ValueError, match=r"reaches 0\.1\.\.\.0\.7 m"):
        arm_inverse(BASE + [0.05, 0.0], L1, L2, BASE)
    with pytest.raises(ValueError, match="from the shoulder"):
        arm_inverse(BASE, L1, L2, BASE)
    with pytest.raises(ValueError, match=r"\(nan, 0\.1\) is not finite"):
        arm_inverse([[0.2, 0.1], [math.nan, 0.1]], L1, L2, BASE)
    with pytest.raises(ValueError, match="elbow"):
        arm_inverse([0.2, 0.1], L1, L2, BASE, "up")


def test_the_jacobian_is_the_derivative_of_forward() -> None:
    rng = np.random.default_rng(3)
    angles = rng.uniform(-math.pi, math.pi, (50, 2))
    jac = arm_jacobian(angles, L1, L2)
    h = 1e-6
    for k in range(2):
        step = np.zeros(2)
        step[k] = h
        numeric = (arm_forward(angles + step, L1, L2, BASE)
                   - arm_forward(angles - step, L1, L2, BASE)) / (2 * h)
        np.testing.assert_allclose(jac[:, :, k], numeric, atol=1e-8)


def arm(**joint_limits: int) -> TwoLink:
    return TwoLink(
        Joint(1, gear_ratio=-2.0, offset_rad=2.0, min_pulse=joint_limits.get("s_min", 0),
              max_pulse=joint_limits.get("s_max", 4095)),
        Joint(2, gear_ratio=1.0, offset_rad=-1.2, min_pulse=joint_limits.get("e_min", 0),
              max_pulse=joint_limits.get("e_max", 4095)),
        Axis(3, 0.01, offset_m=-0.06),
        0.4, 0.4, (0.375, -0.1), "right",
    )


def test_the_mechanism_round_trips_through_pulses_and_picks_the_turn_within_limits() -> None:
    k = arm()
    rng = np.random.default_rng(11)
    points = reachable_points(rng, 300, 0.4, 0.4, np.array([0.375, -0.1]))
    poses = np.column_stack([points, rng.uniform(0.0, 0.05, len(points))])
    pulses = k.inverse(poses)
    np.testing.assert_allclose(k.forward(pulses), poses, atol=1e-9)
    # A reduction of 2: a shoulder turn is half a servo turn... and every pulse target
    # is the turn nearest the middle of the limits.
    assert np.all(np.abs(pulses[:, 0] - 2047.5) <= 4096 * 2 / 2 + 1e-9)
    inside = k.within_limits(pulses)
    lo_hi = np.array([[0, 4095]] * 3)
    manual = np.all((np.rint(pulses) >= lo_hi[:, 0]) & (np.rint(pulses) <= lo_hi[:, 1]), axis=1)
    assert np.array_equal(inside, manual) and inside.any() and not inside.all()
    # The joint angle follows the servo against a negative ratio.
    j = Joint(1, gear_ratio=-3.0, offset_rad=0.2)
    assert float(j.to_rad(300.0)) == pytest.approx(0.2 - 300 * PULSE_RAD / 3)
    assert float(j.to_pulses(j.to_rad(300.0))) == pytest.approx(300.0)
    # With one servo turn per joint turn, an angle and the same angle a turn later agree.
    j1 = Joint(1, offset_rad=-2.6)
    assert float(j1.to_pulses(0.3)) == pytest.approx(float(j1.to_pulses(0.3 + 2 * math.pi)))
    assert 0 <= float(j1.to_pulses(0.3)) <= 4095


def test_the_mechanism_jacobian_is_per_servo_radian_with_z_up() -> None:
    k = arm()
    q = np.array([[1500.0, 2600.0, 1000.0], [1900.0, 1800.0, 3000.0]])
    jac = k.jacobian(q)
    h = 1e-3  # pulses
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        plus, minus = k.forward(q + step), k.forward(q - step)
        plus[:, 2] *= -1  # z = −depth
        minus[:, 2] *= -1
        numeric = (plus - minus) / (2 * h * PULSE_RAD)
        np.testing.assert_allclose(jac[:, :, j], numeric, atol=1e-7)
    gantry = Gantry(Axis(1, 0.125), Axis(2, 0.1), Axis(3, 0.01))
    np.testing.assert_allclose(gantry.jacobian([[5.0, 6.0, 7.0]])[0], np.diag([0.125, 0.1, 0.01]))


def test_segment_distances_are_exact() -> None:
    rng = np.random.default_rng(5)
    for _ in range(50):
        a, b, c = rng.uniform(-1, 1, (3, 2))
        dense = a + np.linspace(0, 1, 20001)[:, None] * (b - a)
        d = np.linalg.norm(dense - c, axis=1)
        near, far = segment_distances(a, b, c)
        assert near == pytest.approx(d.min(), abs=1e-4) and near <= d.min() + 1e-12
        assert far == pytest.approx(d.max(), abs=1e-12)


def test_a_line_between_reachable_ends_can_still_be_unreachable() -> None:
    holed = TwoLink(Joint(1), Joint(2), Axis(3, 0.01, offset_m=-0.06), 0.4, 0.25, (0.0, 0.0))
    start, end = np.array([-0.3, 0.05, 0.02]), np.array([0.3, 0.05, 0.02])
    assert holed.problem(np.vstack([start, end])) is None  # both ends are reachable...
    problem = line_problem(holed, start, end)  # ...the middle passes the hole (r < 0.15)
    assert problem is not None and "too near the shoulder" in problem
    assert "0.05...0.3041 m" in problem and "reaches 0.15...0.65 m" in problem
    assert line_problem(holed, start, start + [0.05, 0.3, 0.0]) is None
    # A joint limit crossed in the middle only: the elbow bends most nearest the shoulder.
    k = arm()
    a, b = np.array([0.1, 0.05, 0.03]), np.array([0.65, 0.05, 0.03])
    ends = k.inverse(np.vstack([a, b]))
    e_max = int(np.ceil(ends[:, 1].max())) + 5
    limited = arm(e_max=e_max)
    assert limited.problem(np.vstack([a, b])) is None
    problem = line_problem(limited, a, b)
    assert problem is not None and "elbow servo (ID 2)" in problem and f"...{e_max}" in problem
    assert line_problem(k, a, b) is None
    assert "not finite" in (line_problem(k, a, [math.nan, 0.0, 0.03]) or "")
