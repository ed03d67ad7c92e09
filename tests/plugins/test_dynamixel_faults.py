"""The hardware notes' §3.4 faults on the ``dynamixel`` robot, beyond the status-packet
faults of test_dynamixel_robot.py: each is survived with bounded recovery and counted, or
ends in DeviceError with the torque off when it cannot be undone behind the operator's back.

The emulated servos start at 2048 pulses: the gantry's transit to x = 0.05 m takes about
3.8 s of simulation time, so faults at 4 s or later strike mid-movement.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from hapticframe.devices import DeviceError, LifecycleState
from hapticframe.kinds import BuildContext, ExploratoryMovement, PhysicalTruth

pytest.importorskip("dynamixel_sdk")

from hapticframe_dynamixel._config import DynamixelRobotConfig
from hapticframe_dynamixel._robot import DynamixelRobot

IDS = (1, 2, 3)
#: The SDK's reply timeout (real time) where faults withhold replies: short for speed, long
#: enough that a loaded machine does not time out on a reply that comes (a spurious recovery
#: would change the states).
REPLY_MS = 60.0


def started(faults: list[dict[str, Any]], **config: Any) -> DynamixelRobot:
    robot = DynamixelRobot(
        DynamixelRobotConfig.model_validate(
            {"faults": faults, "reply_timeout_ms": REPLY_MS, **config}),
        BuildContext(id="gantry", rng=np.random.default_rng(0)),
    )
    robot.configure()
    robot.activate()
    return robot


def line(x0: float = 0.05, x1: float = 0.6) -> ExploratoryMovement:
    return ExploratoryMovement(np.array([x0, 0.25]), np.array([x1, 0.25]), 0.1, depth_m=0.03)


def torques(robot: DynamixelRobot) -> list[int]:
    assert robot.bus is not None
    return [robot.bus.servo(i).get("Torque Enable") for i in IDS]


def steps_until_error(robot: DynamixelRobot, limit: int = 200) -> DeviceError:
    """Step until a DeviceError (which it returns); fail when none comes in ``limit``."""
    for _ in range(limit):
        try:
            state = robot.step()
        except DeviceError as exc:
            return exc
        assert state is not None, "the movement ended without the expected DeviceError"
    raise AssertionError(f"no DeviceError in {limit} steps")


def test_an_unplugged_adapter_is_reopened_and_the_movement_goes_on() -> None:
    """The U2D2 is unplugged for 0.1 s mid-movement (the servos keep their own supply):
    the SDK's serial port fails, the robot waits its backoffs in simulation time, reopens
    the port once the adapter is back, finds the servos holding with torque on, and
    finishes the movement."""
    robot = started([{"kind": "disconnect", "at_s": 4.5, "duration_s": 0.1}])
    try:
        movement = line()
        states = robot.execute(movement)
        assert np.linalg.norm(states[-1].position_m - movement.end_m) <= 0.001 + 1e-9
        assert robot.emulator is not None and robot.emulator.stats["disconnects"] == 1
        assert robot.bus is not None and robot.bus.stats["reconnects"] == 1
        assert robot.bus.stats["power_cycles"] == 0
        assert robot.health.reconnects >= 1
        assert 1 <= robot.health.recoveries <= robot.max_recoveries
        assert robot.lifecycle_state is LifecycleState.ACTIVE and torques(robot) == [1, 1, 1]
        t = np.array([s.timestamp_s for s in states])
        assert np.max(np.diff(t)) >= 0.1  # the backoffs passed in simulation time
    finally:
        robot.close()


def test_a_servo_that_lost_its_supply_is_a_device_error_with_torque_off() -> None:
    robot = started([{"kind": "power_loss", "at_s": 4.5, "params": {"id": 2}}])
    try:
        robot.begin(line())
        error = steps_until_error(robot)
        assert "servo 2 lost its torque" in str(error)
        assert robot.bus is not None and robot.bus.stats["power_cycles"] == 1
        assert robot.health.recoveries >= 1
        assert torques(robot) == [0, 0, 0] and robot.step() is None
        assert robot.lifecycle_state is LifecycleState.ERROR
    finally:
        robot.close()


def test_a_current_spike_shows_in_present_current_and_an_overload_latches() -> None:
    """A stall in sand: 1 A more for 0.2 s is read back and survived; 4 A (beyond the
    3.2 A Current Limit for the 20 ms dwell) latches the overload bit: the servo turns its
    torque off until a reboot, which the robot does not do on its own."""
    robot = started([
        {"kind": "current_spike", "at_s": 4.0, "duration_s": 0.2, "params": {"amps": 1.0}},
        {"kind": "current_spike", "at_s": 5.0, "duration_s": 0.2, "params": {"amps": 4.0}},
    ])
    try:
        robot.begin(line())
        currents = []
        while robot.clock.now() < 4.6:
            assert robot.step() is not None
            currents.append(robot.present_current_a.copy())
        assert np.max(np.array(currents)) == pytest.approx(1.0, abs=0.003)
        assert robot.health.recoveries == 0
        error = steps_until_error(robot)
        assert "hardware error status 0x20" in str(error)
        assert robot.bus is not None and robot.bus.stats["overloads"] >= 1
        assert robot.stats["hardware_errors"] >= 1
        assert torques(robot) == [0, 0, 0] and robot.step() is None
    finally:
        robot.close()


class _Wall:
    """An environment pushing back with 50 N along x (beyond what the x servo holds)."""

    def physical_truth(self, timestamp_s: float) -> PhysicalTruth:
        z = np.zeros(3)
        return PhysicalTruth(timestamp_s, z, np.array([1.0, 0, 0, 0]), z, z, z,
                             np.array([50.0, 0.0, 0.0]), z, 0.0)

    @property
    def truth_time_s(self) -> float:
        return 0.0


def test_an_environment_load_beyond_the_servo_overloads_it() -> None:
    robot = DynamixelRobot(DynamixelRobotConfig(reply_timeout_ms=REPLY_MS),
                           BuildContext(id="gantry", rng=np.random.default_rng(0)))
    robot.couple_environment(_Wall())  # 0.125 m/rad × 50 N = 6.25 N·m ≈ 3.5 A
    robot.configure()
    try:
        robot.activate()
        with pytest.raises(DeviceError, match=r"servo 1 .*0x20"):
            robot.execute(line(0.3, 0.35))
        assert robot.bus is not None and robot.bus.servo(1).hardware_error == 0x20
        assert torques(robot) == [0, 0, 0]
    finally:
        robot.close()


def test_late_and_duplicate_status_packets_are_survived() -> None:
    """A status past the SDK's timeout and a stale duplicate answering the next request:
    retried (the SDK clears the port before each request), counted, and no recovery."""
    robot = started([
        {"kind": "late_reply", "at_s": 4.0, "params": {"id": 2, "delay_s": 0.05}},
        {"kind": "late_duplicate", "at_s": 4.3, "params": {"id": 1}},
        {"kind": "late_reply", "at_s": 4.6, "params": {"id": 3}},
    ])
    try:
        movement = line(0.05, 0.2)
        states = robot.execute(movement)
        assert np.linalg.norm(states[-1].position_m - movement.end_m) <= 0.001 + 1e-9
        assert robot.bus is not None
        assert {s.fault for s in robot.bus.sent if s.fault} == {"late_reply", "late_duplicate"}
        assert robot.health.timeouts >= 2 and robot.stats["retries"] >= 2
        assert robot.health.recoveries == 0
    finally:
        robot.close()
