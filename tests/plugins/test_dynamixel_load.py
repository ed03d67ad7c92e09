"""The environment's load on the emulated servos (EnvironmentCoupled): Present Current
follows ``τ = −Jᵀ f`` for the gantry and the two-link arm."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import (
    BuildContext,
    EnvironmentCoupled,
    ExploratoryMovement,
    PhysicalTruth,
    PhysicalTruthSource,
)
from hapticframe_dynamixel._control_table import CURRENT_UNIT_A
from hapticframe_dynamixel._kinematics import TwoLink, arm_jacobian

pytest.importorskip("dynamixel_sdk")

from hapticframe_dynamixel._config import DynamixelRobotConfig
from hapticframe_dynamixel._robot import DynamixelRobot

IDS = (1, 2, 3)


class FakeSand:
    """A PhysicalTruthSource whose force on the tool is a function of time."""

    def __init__(self, force: Callable[[float], Any]) -> None:
        self.force = force
        self.calls: list[float] = []

    def physical_truth(self, timestamp_s: float) -> PhysicalTruth:
        self.calls.append(timestamp_s)
        zero = np.zeros(3)
        return PhysicalTruth(timestamp_s, zero, np.array([1.0, 0, 0, 0]), zero, zero, zero,
                             np.asarray(self.force(timestamp_s), dtype=float), zero, 0.0)

    @property
    def truth_time_s(self) -> float:
        return self.calls[-1] if self.calls else 0.0


def build(port: str = "emulated", **config: Any) -> DynamixelRobot:
    return DynamixelRobot(DynamixelRobotConfig.model_validate({"port": port, **config}),
                          BuildContext(id="loaded", rng=np.random.default_rng(1)))


def kt(robot: DynamixelRobot) -> float:
    assert robot.bus is not None
    return robot.bus.torque_constant_nm_per_a


def held_currents(robot: DynamixelRobot, end: tuple[float, float]) -> np.ndarray:
    """Move to ``end`` and read the currents of the last (settled) step."""
    robot.execute(ExploratoryMovement(np.array([end[0] - 0.04, end[1]]), np.array(end), 0.05,
                                      depth_m=0.03))
    return robot.present_current_a.copy()


def test_gantry_current_is_minus_j_transpose_f_over_kt_sign_included() -> None:
    force = np.array([6.0, -3.0, 20.0])  # +x drag, −y, and the sand pushing up on the tip
    sand = FakeSand(lambda t: force)
    robot = build()
    assert isinstance(robot, EnvironmentCoupled) and isinstance(sand, PhysicalTruthSource)
    robot.couple_environment(sand)  # at build time, before the bus exists
    robot.configure()
    robot.activate()
    try:
        current = held_currents(robot, (0.3, 0.2))
        lead = np.array([0.125, 0.125, 0.01])  # metres per radian of each axis
        expected = -lead * force / kt(robot)
        assert np.all(np.abs(current - expected) <= CURRENT_UNIT_A / 2 + 1e-9), (current,
                                                                                 expected)
        assert np.array_equal(np.sign(current), np.sign(expected))
        assert robot.bus is not None
        assert robot.bus.servo(1).present_current_a == pytest.approx(current[0])
        assert sand.calls and max(sand.calls) <= robot.clock.now() + 0.01
    finally:
        robot.close()


def test_two_link_current_follows_the_arm_jacobian_and_a_changing_force() -> None:
    f1, f2 = np.array([2.0, 1.0, 5.0]), np.array([-1.5, 2.5, 0.0])
    switch: list[float] = [np.inf]
    sand = FakeSand(lambda t: f1 if t < switch[0] else f2)
    robot = build(kinematics={"type": "two-link"})
    robot.configure()
    robot.couple_environment(sand)  # after configure: the bus's servos get their loads
    robot.activate()
    try:
        k = robot.kinematics
        assert isinstance(k, TwoLink)

        def expected(force: np.ndarray) -> np.ndarray:
            assert robot.bus is not None
            q = np.array([robot.bus.servo(i).get("Present Position") for i in IDS], np.float64)
            angles = np.array([k.shoulder.to_rad(q[0]), k.elbow.to_rad(q[1])], np.float64)
            arm = arm_jacobian(angles, k.l1_m, k.l2_m)  # d(x, y)/d(θ1, θ2)
            # A servo radian turns its joint by 1 / gear_ratio.
            tau = -np.array([arm[:, 0] @ force[:2] / k.shoulder.gear_ratio,
                             arm[:, 1] @ force[:2] / k.elbow.gear_ratio,
                             k.z.metres_per_rad * force[2]])
            return tau / kt(robot)

        current = held_currents(robot, (0.45, 0.3))
        want = expected(f1)
        # Rounding to 2.69 mA, and the Jacobian taken one step earlier (settled: tiny).
        assert np.all(np.abs(current - want) <= CURRENT_UNIT_A / 2 + 0.002 * np.abs(want))
        assert np.array_equal(np.sign(current), np.sign(want))
        switch[0] = robot.clock.now() + 0.001
        current = held_currents(robot, (0.45, 0.25))
        want = expected(f2)
        assert np.all(np.abs(current - want) <= CURRENT_UNIT_A / 2 + 0.002 * np.abs(want))
        assert current[2] == pytest.approx(0.0, abs=CURRENT_UNIT_A)  # no vertical force now
    finally:
        robot.close()


def test_the_load_keeps_runs_deterministic() -> None:
    def run() -> tuple[np.ndarray, np.ndarray]:
        sand = FakeSand(lambda t: [3.0 * np.sin(4 * t), 2.0, 10.0 * t])
        robot = build(kinematics={"type": "two-link"})
        robot.couple_environment(sand)
        robot.configure()
        robot.activate()
        try:
            currents, rows = [], []
            robot.begin(ExploratoryMovement(np.array([0.3, 0.2]), np.array([0.4, 0.25]), 0.08,
                                            depth_m=0.03))
            while (state := robot.step()) is not None:
                currents.append(robot.present_current_a.copy())
                rows.append([state.timestamp_s, *state.position_m, state.depth_m])
            return np.array(rows), np.array(currents)
        finally:
            robot.close()

    rows, currents = run()
    rows_again, currents_again = run()
    assert np.array_equal(rows, rows_again) and np.array_equal(currents, currents_again)
    assert np.ptp(currents[:, 2]) > 10 * CURRENT_UNIT_A  # the load did change over time


def test_a_real_port_cannot_be_coupled() -> None:
    robot = build(port="/dev/ttyUSB0")
    with pytest.raises(ValueError, match=r"drives real servos on /dev/ttyUSB0.*'emulated'"):
        robot.couple_environment(FakeSand(lambda t: np.zeros(3)))
    assert robot.environment is None
