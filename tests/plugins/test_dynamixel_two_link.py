"""The ``dynamixel`` robot as a planar two-link arm on a vertical axis, on the emulated bus
(the real ``dynamixel_sdk`` through a pty, in simulation time)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, ExploratoryMovement
from hapticframe.testing import checks_for, parametrize_with_checks
from hapticframe_dynamixel import plugin as dxl_plugin
from hapticframe_dynamixel._config import DynamixelRobotConfig
from hapticframe_dynamixel._kinematics import TwoLink, arm_forward

pytest.importorskip("dynamixel_sdk")

from hapticframe_dynamixel._robot import DynamixelRobot

SPEC = next(iter(dxl_plugin.hapticframe_robots()))
IDS = (1, 2, 3)


def build(kinematics: dict[str, Any] | None = None, **config: Any) -> DynamixelRobot:
    return DynamixelRobot(
        DynamixelRobotConfig.model_validate(
            {"kinematics": {"type": "two-link", **(kinematics or {})}, **config}),
        BuildContext(id="arm", rng=np.random.default_rng(0)),
    )


@pytest.fixture
def robot() -> Iterator[DynamixelRobot]:
    robot = build()
    robot.configure()
    robot.activate()
    try:
        yield robot
    finally:
        robot.close()


def test_the_arm_follows_a_straight_line_at_constant_speed_and_depth(
    robot: DynamixelRobot,
) -> None:
    assert isinstance(robot.kinematics, TwoLink)
    movement = ExploratoryMovement(np.array([0.1, 0.1]), np.array([0.65, 0.4]), 0.06,
                                   depth_m=0.03)
    states = robot.execute(movement)
    pos = np.vstack([s.position_m for s in states])
    t = np.array([s.timestamp_s for s in states])
    direction = (movement.end_m - movement.start_m) / movement.length_m
    offset = pos - movement.start_m
    cross_track = offset[:, 0] * direction[1] - offset[:, 1] * direction[0]
    assert np.max(np.abs(cross_track)) < 1e-3  # on the line, despite the joint-space lag
    assert np.linalg.norm(pos[0] - movement.start_m) < 0.002
    assert np.linalg.norm(pos[-1] - movement.end_m) <= 0.001 + 1e-9
    assert robot.halt_reason == ""
    assert all(abs(s.depth_m - 0.03) < 0.001 for s in states)
    assert all(s.heading_rad == pytest.approx(movement.heading_rad) for s in states)
    duration = movement.length_m / movement.speed_m_per_s
    cruise = (t > t[0] + 0.3) & (t < t[0] + duration - 0.1)
    speeds = np.array([s.speed_m_per_s for s in states])[cruise]
    assert np.mean(speeds) == pytest.approx(0.06, rel=0.03)
    # The recorded pose is forward kinematics of the servos' positions, read back.
    assert robot.bus is not None
    pulses = [robot.bus.servo(i).get("Present Position") for i in IDS]
    k = robot.kinematics
    angles = np.array([float(k.shoulder.to_rad(pulses[0])), float(k.elbow.to_rad(pulses[1]))])
    reference = arm_forward(angles, k.l1_m, k.l2_m, k.base_m)
    assert np.linalg.norm(reference - pos[-1]) < 1e-3  # the servos kept settling since


def test_the_servos_are_set_up_with_the_joint_limits() -> None:
    robot = build({"shoulder": {"id": 1, "gear_ratio": 2.0, "offset_rad": -1.06,
                                "min_pulse": 100, "max_pulse": 4000}})
    try:
        robot.configure()
        assert robot.bus is not None
        assert robot.bus.servo(1).get("Min Position Limit") == 100
        assert robot.bus.servo(1).get("Max Position Limit") == 4000
        assert [robot.bus.servo(i).get("Operating Mode") for i in IDS] == [3, 3, 3]
    finally:
        robot.close()


def test_a_workspace_the_arm_cannot_reach_is_refused_at_build_with_its_location() -> None:
    with pytest.raises(ValueError, match=r"robot 'arm': the workspace .* is 0\.7075 m from "
                       r"the shoulder .* reaches 0\.1...0\.5 m"):
        build({"l1_m": 0.3, "l2_m": 0.2})
    # A shoulder inside the workspace of an arm with a hole around it.
    with pytest.raises(ValueError, match=r"\(0\.375, 0\.25\) is 0 m from the shoulder"):
        build({"l1_m": 0.5, "l2_m": 0.4, "base_m": (0.375, 0.25)})
    # Joint limits that cut the workspace: the servo and the pose are named.
    with pytest.raises(ValueError, match=r"needs the elbow servo \(ID 2\) at pulse \d+, "
                       r"beyond its limits 0...3000"):
        build({"elbow": {"id": 2, "gear_ratio": 2.0, "offset_rad": 0.35, "max_pulse": 3000}})
    # The other branch with the right branch's offsets: out of the joint ranges.
    with pytest.raises(ValueError, match="shoulder servo"):
        build({"elbow_side": "left"})


def test_a_line_is_refused_before_any_motion_when_its_middle_is_unreachable(
    robot: DynamixelRobot,
) -> None:
    """Both ends within reach and limits, the middle beyond the elbow's limit: begin()
    refuses it whole. (The build-time check would refuse such limits over the workspace,
    so the robot's kinematics are narrowed after it was built.)"""
    k = robot.kinematics
    assert isinstance(k, TwoLink)
    a, b = np.array([0.1, 0.05]), np.array([0.65, 0.05])
    ends = k.inverse(np.array([[*a, 0.03], [*b, 0.03]]))
    middle = k.inverse([0.375, 0.05, 0.03])
    assert middle[1] > ends[:, 1].max() + 20  # the elbow bends most near the shoulder
    limit = int(ends[:, 1].max()) + 10
    robot.kinematics = dataclasses.replace(
        k, elbow=dataclasses.replace(k.elbow, max_pulse=limit))
    assert robot.bus is not None
    before = robot.bus.stats["instructions"]
    with pytest.raises(ValueError, match=f"elbow servo \\(ID 2\\) .* beyond its limits "
                       f"0...{limit}"):
        robot.begin(ExploratoryMovement(a, b, 0.05, depth_m=0.03))
    with pytest.raises(ValueError, match="z servo"):  # too deep for the vertical axis
        robot.begin(ExploratoryMovement(a, a + [0.05, 0.0], 0.05, depth_m=0.3))
    assert robot.step() is None
    assert robot.bus.stats["instructions"] == before  # nothing sent


TWO_LINK = dataclasses.replace(SPEC, check_config={"kinematics": {"type": "two-link"}})


def test_the_kit_applies_every_robot_check_to_the_two_link_arm() -> None:
    assert {"check_robot_contract", "check_robot_stops_at_once", "check_robot_extremes",
            "check_robot_refuses_outside_workspace", "check_deterministic"} <= {
        check.__name__ for check in checks_for(TWO_LINK)}


@parametrize_with_checks([TWO_LINK])
def test_the_kit_passes_on_the_two_link_arm(spec: Any, check: Any) -> None:
    check(spec)
