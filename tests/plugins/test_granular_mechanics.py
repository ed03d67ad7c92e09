"""The shared granular mechanics (hapticframe_granular) and the two plugins that use them.

Hand-worked values come from the dissertation's formulas (Table 3.1, Figure 3.2); the last
tests hold the sandbox simulator and the failure-zone sensor model to the shared functions,
so that the two cannot drift apart again.
"""

from __future__ import annotations

import ast
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import hapticframe_granular
from hapticframe import Circle, Material, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement, MovementResult
from hapticframe_failure_zone import FailureZoneAngleWarning, FailureZoneConfig, FailureZoneKernel
from hapticframe_granular import (
    SIDE_CRESCENT_ANGLE_CAP,
    arthur_angle,
    rupture_distance,
    side_crescent_angle,
    side_crescent_angle_analytic,
)
from hapticframe_sandbox import SandboxRobot, SandboxRobotConfig

RAD = math.radians
VERTICAL = math.pi / 2
BETA = RAD(31.5)
#: cot 31.5°, worked out independently: cos/sin at 31.5° to 16 digits.
COT_31_5 = 0.8526401643540922 / 0.5224985647159488


# --- the Arthur angle -------------------------------------------------------------------------


def test_arthur_angle_of_the_thesis_sand_mixture() -> None:
    # Table 3.1, note †: 45° − (42° + 12°)/4 = 45° − 13.5° = 31.5°.
    assert arthur_angle(RAD(42.0), RAD(12.0)) == pytest.approx(RAD(31.5), abs=1e-15)
    # 45° − (30° + 0°)/4 = 37.5°; 45° − (35° + 5°)/4 = 35°.
    assert math.degrees(arthur_angle(RAD(30.0), 0.0)) == pytest.approx(37.5, abs=1e-12)
    assert math.degrees(arthur_angle(RAD(35.0), RAD(5.0))) == pytest.approx(35.0, abs=1e-12)
    # Every value is in radians and falls as the material gets stronger or more dilatant.
    assert arthur_angle(RAD(40.0), RAD(10.0)) < arthur_angle(RAD(30.0), RAD(10.0))
    assert arthur_angle(RAD(40.0), RAD(10.0)) < arthur_angle(RAD(40.0), 0.0)


@pytest.mark.parametrize(
    ("phi", "psi", "bad"),
    [
        (0.0, 0.0, "friction_angle_rad"),
        (-0.1, 0.0, "friction_angle_rad"),
        (math.pi / 2, 0.0, "friction_angle_rad"),
        (math.nan, 0.0, "friction_angle_rad"),
        (math.inf, 0.0, "friction_angle_rad"),
        (0.5, -1e-9, "dilation_angle_rad"),
        (0.5, math.pi / 2, "dilation_angle_rad"),
        (0.5, math.nan, "dilation_angle_rad"),
    ],
)
def test_arthur_angle_rejects_angles_outside_its_domain(phi: float, psi: float, bad: str) -> None:
    with pytest.raises(ValueError, match=bad):
        arthur_angle(phi, psi)
    with pytest.raises(ValueError, match=bad):
        arthur_angle(np.array([0.5, phi]), np.array([0.1, psi]))


def test_arthur_angle_stays_in_its_range_at_the_edges_of_the_domain() -> None:
    tiny = 1e-300
    assert arthur_angle(tiny, 0.0) == pytest.approx(math.pi / 4)
    widest = np.nextafter(math.pi / 2, 0.0)
    beta = arthur_angle(widest, widest)
    assert 0.0 < beta < 1e-15


# --- the rupture distance ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("depth_cm", "table_cm"), [(4.4, 7.1), (3.4, 5.5), (2.9, 4.7), (2.65, 4.3)]
)
def test_rupture_distance_matches_table_3_1(depth_cm: float, table_cm: float) -> None:
    r = rupture_distance(depth_cm / 100, VERTICAL, BETA)
    # By hand: d cot 31.5° = 7.180, 5.548, 4.732, 4.324 cm; the table truncates to mm.
    assert r == pytest.approx(depth_cm / 100 * COT_31_5, rel=1e-12)
    assert math.floor(r * 1000 + 1e-9) / 10 == pytest.approx(table_cm)


def test_rupture_distance_of_vertical_raking_is_exactly_d_cot_beta() -> None:
    # cot 90° must be 0, not the 6e-17 that cos(π/2)/sin(π/2) evaluates to.
    assert rupture_distance(0.044, VERTICAL, BETA) == 0.044 / math.tan(BETA)
    assert rupture_distance(0.044, VERTICAL, RAD(45.0)) == pytest.approx(0.044, rel=1e-15)
    np.testing.assert_array_equal(
        rupture_distance(np.array([0.044]), VERTICAL, BETA), [0.044 / math.tan(BETA)]
    )


def test_rupture_distance_of_an_inclined_plate() -> None:
    # α = 60°, β = 45°: r = d (1/√3 + 1) = 0.03 × 1.5773503 = 0.0473205 m.
    assert rupture_distance(0.03, RAD(60.0), RAD(45.0)) == pytest.approx(0.0473205, abs=1e-7)
    # α = 45°, β = 45°: r = 2d.
    assert rupture_distance(0.02, RAD(45.0), RAD(45.0)) == pytest.approx(0.04, rel=1e-14)
    # Leaning back (α > 90°) shortens the wedge: α = 120°, β = 45°: d (1 − 1/√3).
    assert rupture_distance(0.03, RAD(120.0), RAD(45.0)) == pytest.approx(0.0126795, abs=1e-7)


def test_rupture_distance_is_zero_where_the_model_has_no_wedge() -> None:
    # α > π − β: cot α + cot β < 0 (170°: −5.671 + 1.632); the documented clip gives 0.
    assert rupture_distance(0.044, RAD(170.0), BETA) == 0.0
    np.testing.assert_array_equal(
        rupture_distance(0.044, np.radians([90.0, 170.0]), BETA), [0.044 * COT_31_5, 0.0]
    )
    # Exactly at α = π − β the wedge vanishes: within rounding of 0, never negative.
    edge = rupture_distance(0.044, math.pi - BETA, BETA)
    assert 0.0 <= edge < 1e-15


def test_rupture_distance_at_zero_tiny_and_huge_depths() -> None:
    assert rupture_distance(0.0, VERTICAL, BETA) == 0.0
    assert rupture_distance(1e-300, VERTICAL, BETA) == pytest.approx(1e-300 * COT_31_5)
    assert rupture_distance(1e6, VERTICAL, BETA) == pytest.approx(1e6 * COT_31_5)
    # Nearly flat shear bands and plates give long but finite wedges.
    assert math.isfinite(rupture_distance(0.044, 1e-12, 1e-12))


@pytest.mark.parametrize(
    ("depth", "alpha", "beta", "bad"),
    [
        (-0.01, VERTICAL, BETA, "depth_m"),
        (math.nan, VERTICAL, BETA, "depth_m"),
        (math.inf, VERTICAL, BETA, "depth_m"),
        (0.04, 0.0, BETA, "rake_angle_rad"),
        (0.04, math.pi, BETA, "rake_angle_rad"),
        (0.04, math.nan, BETA, "rake_angle_rad"),
        (0.04, VERTICAL, 0.0, "shear_band_angle_rad"),
        (0.04, VERTICAL, math.pi / 2, "shear_band_angle_rad"),
        (0.04, VERTICAL, -BETA, "shear_band_angle_rad"),
        # Degrees passed by mistake are caught: 31.5 is far outside (0, π/2).
        (0.04, VERTICAL, 31.5, "shear_band_angle_rad"),
    ],
)
def test_rupture_distance_rejects_bad_input(
    depth: float, alpha: float, beta: float, bad: str
) -> None:
    with pytest.raises(ValueError, match=bad):
        rupture_distance(depth, alpha, beta)
    with pytest.raises(ValueError, match=bad):
        rupture_distance(np.array([0.01, depth]), alpha, beta)


# --- the side-crescent angle ------------------------------------------------------------------


def test_side_crescent_angle_follows_table_3_1_up_to_the_cap() -> None:
    degrees = [math.degrees(side_crescent_angle(n)) for n in range(8)]
    # (50 + 7n)° = 50, 57, 64, 71, 78, 85, then 92 and 99 capped at 90.
    np.testing.assert_allclose(degrees, [50, 57, 64, 71, 78, 85, 90, 90], atol=1e-12)
    assert side_crescent_angle(0) == RAD(50.0)
    assert side_crescent_angle(6) == SIDE_CRESCENT_ANGLE_CAP == math.pi / 2
    assert side_crescent_angle(1000) == math.pi / 2
    assert side_crescent_angle(10**400) == math.pi / 2  # beyond float range
    # Other constants follow the same line and the same cap.
    assert side_crescent_angle(2, base_deg=30.0, step_deg=5.0) == RAD(40.0)
    assert side_crescent_angle(10**400, base_deg=30.0, step_deg=0.0) == RAD(30.0)
    assert side_crescent_angle(0, base_deg=120.0) == math.pi / 2


def test_side_crescent_angle_counts() -> None:
    assert side_crescent_angle(3.0) == side_crescent_angle(3) == side_crescent_angle(np.int64(3))
    for bad in (-1, 1.5, math.nan, math.inf, -0.5):
        with pytest.raises(ValueError, match="pair_count"):
            side_crescent_angle(bad)
    for wrong in (True, "2", None):
        with pytest.raises(TypeError, match="pair_count"):
            side_crescent_angle(wrong)  # type: ignore[arg-type]
    for name, kwargs in (
        ("base_deg", {"base_deg": -1.0}),
        ("base_deg", {"base_deg": math.nan}),
        ("step_deg", {"step_deg": math.inf}),
    ):
        with pytest.raises(ValueError, match=name):
            side_crescent_angle(1, **kwargs)


def test_side_crescent_angle_of_arrays() -> None:
    eta = side_crescent_angle(np.array([0, 1, 6, 100]))
    np.testing.assert_array_equal(eta, [RAD(50.0), RAD(57.0), math.pi / 2, math.pi / 2])
    assert eta.dtype == np.float64
    np.testing.assert_array_equal(side_crescent_angle([[0.0, 2.0]]), [[RAD(50.0), RAD(64.0)]])
    with pytest.raises(ValueError, match="pair_count"):
        side_crescent_angle(np.array([0, -1]))
    with pytest.raises(ValueError, match="pair_count"):
        side_crescent_angle(np.array([0.0, 0.5]))
    with pytest.raises(TypeError, match="pair_count"):
        side_crescent_angle(np.array([True]))


def test_analytic_side_angle_is_capped_like_the_empirical_one() -> None:
    # r = 7.1 cm, α = 90°: (6.03 + 0.460·7.1 + 0.0904·90) / 7.1 = 17.432 / 7.1 = 2.4552.
    eta, argument = side_crescent_angle_analytic(0.071, VERTICAL)
    assert argument == pytest.approx(17.432 / 7.1, rel=1e-12)
    assert eta == SIDE_CRESCENT_ANGLE_CAP
    # r = 50 cm: (6.03 + 23.0 + 8.136) / 50 = 0.74332, asin = 0.838020 rad (48.02°).
    eta, argument = side_crescent_angle_analytic(0.5, VERTICAL)
    assert argument == pytest.approx(0.74332, rel=1e-12)
    assert eta == pytest.approx(0.838020, abs=1e-6)
    # A huge range tends to asin(0.460) from above; a tiny one saturates.
    assert side_crescent_angle_analytic(1e6, VERTICAL)[0] == pytest.approx(math.asin(0.46))
    assert side_crescent_angle_analytic(1e-300, VERTICAL)[0] == math.pi / 2
    for r, alpha, bad in (
        (0.0, VERTICAL, "range_m"),
        (math.nan, VERTICAL, "range_m"),
        (0.05, 0.0, "rake_angle_rad"),
        (0.05, math.pi, "rake_angle_rad"),
    ):
        with pytest.raises(ValueError, match=bad):
            side_crescent_angle_analytic(r, alpha)


# --- shapes: scalars, arrays, empty arrays -----------------------------------------------------


def test_scalars_give_floats_and_arrays_give_arrays() -> None:
    for value in (
        arthur_angle(0.7, 0.2),
        arthur_angle(np.float64(0.7), np.float32(0.2)),
        rupture_distance(0.04, VERTICAL, BETA),
        rupture_distance(np.float64(0.04), np.float64(VERTICAL), BETA),
        side_crescent_angle(2),
    ):
        assert type(value) is float
    zero_d = rupture_distance(np.array(0.04), VERTICAL, BETA)
    assert isinstance(zero_d, np.ndarray) and zero_d.shape == ()
    grid = rupture_distance(np.full((2, 3), 0.04), np.radians([[60.0], [90.0]]), BETA)
    assert grid.shape == (2, 3) and grid.dtype == np.float64
    np.testing.assert_allclose(grid[1], 0.04 * COT_31_5, rtol=1e-14)
    betas = arthur_angle(np.radians([30.0, 42.0]), np.radians([0.0, 12.0]))
    np.testing.assert_allclose(np.degrees(betas), [37.5, 31.5], atol=1e-12)


def test_empty_arrays_give_empty_arrays() -> None:
    empty = np.array([], dtype=np.float64)
    for value in (
        arthur_angle(empty, 0.1),
        rupture_distance(empty, VERTICAL, BETA),
        rupture_distance([], VERTICAL, BETA),
        side_crescent_angle(np.array([], dtype=np.int64)),
    ):
        assert isinstance(value, np.ndarray) and value.shape == (0,)
        assert value.dtype == np.float64


def test_the_scalar_and_array_paths_agree() -> None:
    rng = np.random.default_rng(7)
    depth = rng.uniform(0.0, 0.1, 200)
    alpha = rng.uniform(0.1, 3.0, 200)
    beta = rng.uniform(0.05, 1.5, 200)
    scalar = [rupture_distance(float(d), float(a), float(b))
              for d, a, b in zip(depth, alpha, beta, strict=True)]
    np.testing.assert_allclose(rupture_distance(depth, alpha, beta), scalar, rtol=1e-14, atol=0)
    phi = rng.uniform(0.01, 1.5, 50)
    psi = rng.uniform(0.0, 1.5, 50)
    scalar = [arthur_angle(float(p), float(q)) for p, q in zip(phi, psi, strict=True)]
    np.testing.assert_allclose(arthur_angle(phi, psi), scalar, rtol=1e-15, atol=0)
    counts = np.arange(20)
    assert side_crescent_angle(counts).tolist() == [side_crescent_angle(int(n)) for n in counts]


# --- the sandbox and the failure-zone model use exactly these functions -----------------------

#: A material other than the default, so that each plugin must take β from φ and ψ.
MATERIAL = Material(friction_angle_deg=35.0, dilation_angle_deg=5.0)
CENTRE, RADIUS = (0.3, 0.25), 0.04


def _sandbox_truth(movements: int) -> tuple[SandboxRobot, list]:
    """Short movements that each start inside the failure zone's reach of a circle."""
    scene = Scene(material=MATERIAL, objects=[Circle(center_m=CENTRE, radius_m=RADIUS)])
    robot = SandboxRobot(
        SandboxRobotConfig(), BuildContext(id="arm", rng=np.random.default_rng(0), scene=scene)
    )
    x = CENTRE[0] - RADIUS - 0.03
    for index in range(movements):
        movement = ExploratoryMovement((x, CENTRE[1]), (x + 0.01, CENTRE[1]))
        robot.begin(movement)
        while robot.step() is not None:
            pass
        robot.on_movement_end(
            MovementResult(index, movement, bool(robot.halt_reason), robot.halt_reason, None)
        )
    return robot, list(robot.movements)


def test_the_sandbox_uses_the_shared_mechanics() -> None:
    robot, truth = _sandbox_truth(14)
    beta = arthur_angle(RAD(35.0), RAD(5.0))
    assert robot.shear_band_angle_deg == pytest.approx(35.0, abs=1e-12)
    assert all(m.interacted for m in truth)
    for k, movement in enumerate(truth):
        assert movement.rupture_distance_m == rupture_distance(movement.depth_m, VERTICAL, beta)
        assert RAD(movement.side_crescent_angle_deg) == pytest.approx(
            side_crescent_angle(k // 2), abs=1e-15
        )
    # Seven pairs: the line (50 + 7·6)° = 92° has reached the cap.
    assert RAD(truth[-1].side_crescent_angle_deg) == pytest.approx(math.pi / 2, abs=1e-15)


@pytest.mark.parametrize("schedule", ["hybrid", "empirical", "analytic"])
def test_the_failure_zone_model_uses_the_shared_mechanics(schedule: str) -> None:
    model = FailureZoneKernel(
        FailureZoneConfig(schedule=schedule, max_range_m=10.0),
        BuildContext("soil", np.random.default_rng(0), scene=Scene(material=MATERIAL)),
    )
    beta = arthur_angle(RAD(35.0), RAD(5.0))
    assert model.shear_band_angle_rad == beta
    for k in range(16):
        depth = 0.044 - 0.001 * k
        with warnings.catch_warnings():  # the analytic formula's clipping, tested elsewhere
            warnings.simplefilter("ignore", FailureZoneAngleWarning)
            reach, _, eta = model.parameters(depth_m=depth)
        if schedule != "empirical":
            assert reach == rupture_distance(depth, VERTICAL, beta)
        if schedule == "analytic":
            assert eta == side_crescent_angle_analytic(reach, VERTICAL)[0]
        else:
            assert eta == side_crescent_angle(k // 2)
        movement = ExploratoryMovement((0.0, 0.0), (0.1, 0.0))
        model.on_movement_end(MovementResult(k, movement, True, "interaction", None, "jamming"))
    if schedule != "analytic":
        assert eta == math.pi / 2  # the same cap as the sandbox


def test_sandbox_and_failure_zone_agree_movement_by_movement() -> None:
    _, truth = _sandbox_truth(14)
    model = FailureZoneKernel(
        FailureZoneConfig(schedule="hybrid", max_range_m=10.0),
        BuildContext("soil", np.random.default_rng(0), scene=Scene(material=MATERIAL)),
    )
    for index, movement in enumerate(truth):
        reach, _, eta = model.parameters(depth_m=movement.depth_m)
        assert reach == movement.rupture_distance_m
        assert eta == pytest.approx(RAD(movement.side_crescent_angle_deg), abs=1e-15)
        done = ExploratoryMovement((0.0, 0.0), (0.1, 0.0))
        model.on_movement_end(MovementResult(index, done, True, "interaction", None, "jamming"))


def test_no_plugin_keeps_its_own_copy_of_the_mechanics() -> None:
    plugins = Path(hapticframe_granular.__file__).parent.parent
    home = Path(hapticframe_granular.__file__).parent
    copies = []
    for path in plugins.rglob("*.py"):
        if home in path.parents:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and any(
                word in node.name.lower() for word in ("arthur", "rupture_distance", "crescent")
            ):
                copies.append(f"{path.relative_to(plugins)}: {node.name}")
    assert not copies, copies
