"""The ``dynamixel`` robot against real XM430-W350 servos.

Skipped unless pytest runs with ``--hardware`` and ``HAPTICFRAME_DYNAMIXEL_PORT`` names the
U2D2's port (servos at 1 Mbit/s). The robot's config is the default gantry (IDs 1, 2, 3),
or the YAML mapping in the file ``HAPTICFRAME_DYNAMIXEL_CONFIG`` names (e.g. a
``kinematics: {type: two-link, ...}`` and its ``workspace``); ``port`` comes from the
environment either way::

    HAPTICFRAME_DYNAMIXEL_PORT=/dev/serial/by-id/usb-FTDI_..._XXXX-if00-port0 \\
        python -m pytest --hardware tests/hardware/test_dynamixel_hardware.py

The mechanism moves: keep clear of it. Every movement is 2 cm at 2 cm/s around the middle
of the workspace; the torque is off when each test ends.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from hapticframe.devices import LifecycleState
from hapticframe.kinds import BuildContext, ExploratoryMovement, RobotState

pytestmark = pytest.mark.hardware

ADDR_TORQUE = 64
ADDR_GOAL, ADDR_PRESENT = 116, 132


def _config() -> dict[str, Any]:
    port = os.environ.get("HAPTICFRAME_DYNAMIXEL_PORT")
    if not port:
        pytest.skip("set HAPTICFRAME_DYNAMIXEL_PORT to the U2D2's port (servos at 1 Mbit/s)")
    config: dict[str, Any] = {}
    path = os.environ.get("HAPTICFRAME_DYNAMIXEL_CONFIG")
    if path:
        loaded = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
        assert isinstance(loaded, dict), f"{path}: expected a mapping of the robot's config"
        config.update(loaded)
    config["port"] = port
    config.pop("faults", None)
    return config


@pytest.fixture
def robot() -> Iterator[Any]:
    pytest.importorskip("dynamixel_sdk")
    from hapticframe_dynamixel._config import DynamixelRobotConfig
    from hapticframe_dynamixel._robot import DynamixelRobot

    config = DynamixelRobotConfig(**_config())
    robot = DynamixelRobot(config, BuildContext(id="dynamixel", rng=np.random.default_rng(0)))
    robot.configure()
    try:
        robot.activate()
        yield robot
    finally:
        robot.close()


def _read(robot: Any, servo_id: int, address: int, size: int) -> int:
    fn = {1: robot._ph.read1ByteTxRx, 4: robot._ph.read4ByteTxRx}[size]
    value, comm, error = fn(robot._port, servo_id, address)
    assert comm == 0 and error == 0, (servo_id, comm, error)
    return int(value) - (1 << 32) if size == 4 and value >= 1 << 31 else int(value)


def _short_line(robot: Any) -> ExploratoryMovement:
    center = robot.workspace.center_m
    return ExploratoryMovement(center - [0.01, 0.0], center + [0.01, 0.0], 0.02)


def _run(robot: Any, movement: ExploratoryMovement, max_steps: int = 1000) -> list[RobotState]:
    """Step as a run does, paced by the wall clock at the control rate."""
    robot.begin(movement)
    states = []
    period = 1.0 / robot.control_rate_hz
    for _ in range(max_steps):
        state = robot.step()
        if state is None:
            break
        states.append(state)
        time.sleep(period)
    return states


def test_configure_and_activate_identify_the_xm430s(robot: Any) -> None:
    assert robot.live is True and robot.lifecycle_state is LifecycleState.ACTIVE
    for servo_id in robot.kinematics.ids:  # configure pinged each: an XM430-W350 (1020)
        model, comm, _ = robot._ph.ping(robot._port, servo_id)
        assert (model, comm) == (1020, 0)
        assert _read(robot, servo_id, ADDR_TORQUE, 1) == 1
    assert np.all(np.isfinite(robot.state.position_m))
    assert robot.health.recoveries == 0


def test_a_short_slow_movement_reaches_its_end(robot: Any) -> None:
    movement = _short_line(robot)
    states = _run(robot, movement)
    assert states, "no states"
    pos = np.vstack([s.position_m for s in states])
    assert np.linalg.norm(pos[0] - movement.start_m) < 0.005
    assert np.linalg.norm(pos[-1] - movement.end_m) < 0.002
    assert robot.halt_reason == ""
    assert np.all(np.diff([s.timestamp_s for s in states]) > 0)
    assert np.all(np.abs(robot.present_current_a) < 2.0)  # no stall on a free move


def test_halt_holds_the_present_position(robot: Any) -> None:
    movement = _short_line(robot)
    robot.begin(movement)
    for _ in range(10):
        assert robot.step() is not None
        time.sleep(1.0 / robot.control_rate_hz)
    robot.halt("hardware test")
    assert robot.step() is None
    held = [_read(robot, i, ADDR_PRESENT, 4) for i in robot.kinematics.ids]
    time.sleep(0.5)
    for servo_id, before in zip(robot.kinematics.ids, held, strict=True):
        assert abs(_read(robot, servo_id, ADDR_GOAL, 4) - before) <= 2
        assert abs(_read(robot, servo_id, ADDR_PRESENT, 4) - before) <= 5
        assert _read(robot, servo_id, ADDR_TORQUE, 1) == 1  # holding, not limp


def test_deactivate_leaves_the_torque_off(robot: Any) -> None:
    robot.deactivate()
    assert robot.lifecycle_state is LifecycleState.INACTIVE
    for servo_id in robot.kinematics.ids:
        assert _read(robot, servo_id, ADDR_TORQUE, 1) == 0
