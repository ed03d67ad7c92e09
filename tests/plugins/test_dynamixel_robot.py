"""The ``dynamixel`` robot on the emulated bus: the real ``dynamixel_sdk`` through a pty, in
simulation time (a FakeClock that each step advances)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from hapticframe.devices import DeviceError, FakeClock, LifecycleState
from hapticframe.kinds import BuildContext, ExploratoryMovement, Robot
from hapticframe.testing import checks_for, make_component
from hapticframe_dynamixel import XM430_W350_MODEL_NUMBER
from hapticframe_dynamixel import plugin as dxl_plugin
from hapticframe_dynamixel._config import AxisConfig, DynamixelRobotConfig, GantryConfig
from hapticframe_dynamixel._kinematics import Axis, Gantry
from hapticframe_dynamixel._robot import RECOVERY_BACKOFF_S, DynamixelRobot

pytest.importorskip("dynamixel_sdk")

SPEC = next(iter(dxl_plugin.hapticframe_robots()))
IDS = (1, 2, 3)
#: The SDK's reply timeout (real time) where faults withhold replies: short for speed, long
#: enough that a loaded machine does not time out on a reply that comes (a spurious recovery
#: would change the states).
REPLY_MS = 60.0


def build(seed: int = 0, **config: Any) -> DynamixelRobot:
    robot = DynamixelRobot(
        DynamixelRobotConfig(**config), BuildContext(id="gantry", rng=np.random.default_rng(seed))
    )
    return robot


@pytest.fixture
def robot() -> Iterator[DynamixelRobot]:
    robot = build()
    robot.configure()
    robot.activate()
    try:
        yield robot
    finally:
        robot.close()


def torques(robot: DynamixelRobot) -> list[int]:
    assert robot.bus is not None
    return [robot.bus.servo(i).get("Torque Enable") for i in IDS]


def line(x0: float, x1: float, y: float = 0.25, speed: float = 0.05) -> ExploratoryMovement:
    return ExploratoryMovement(np.array([x0, y]), np.array([x1, y]), speed, depth_m=0.03)


# --- kinematics ---------------------------------------------------------------------------------


def test_gantry_round_trips_and_limits() -> None:
    gantry = Gantry(Axis(1, 0.125), Axis(2, 0.1, offset_m=-0.2), Axis(3, 0.01, offset_m=-0.06,
                                                                       min_pulse=100))
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(0, 0.7, 50), rng.uniform(-0.1, 0.4, 50),
                             rng.uniform(0.0, 0.05, 50)])
    joints = gantry.inverse(poses)
    np.testing.assert_allclose(gantry.forward(joints), poses, atol=1e-12)
    np.testing.assert_allclose(gantry.inverse(gantry.forward(joints)), joints, atol=1e-9)
    # depth = -z: deeper is a smaller z, i.e. fewer pulses on a positive lead.
    assert gantry.inverse([0, 0, 0.04])[2] < gantry.inverse([0, 0, 0.01])[2]
    # One pulse of x is 0.125 m/rad * 2π/4096.
    assert gantry.forward([1, 0, 0])[0] == pytest.approx(0.125 * 2 * np.pi / 4096)
    assert gantry.within_limits([[100, 100, 100], [4095, 0, 100]]).tolist() == [True, True]
    assert gantry.within_limits([[4096, 0, 100], [0, 0, 99], [-1, 5, 200]]).tolist() == [
        False, False, False]
    (x_lo, x_hi), _, (d_lo, d_hi) = gantry.reach()
    assert x_lo == 0.0 and x_hi == pytest.approx(0.125 * 4095 * 2 * np.pi / 4096)
    assert d_lo < d_hi


def test_a_workspace_beyond_the_joint_limits_is_refused_at_build() -> None:
    short = GantryConfig(x=AxisConfig(id=1, metres_per_rad=0.05))  # reaches 0.31 m
    with pytest.raises(ValueError, match=r"position limits: the pose \(0\.75, 0, 0\.044\) "
                       r"\(x, y, depth\) needs the x servo \(ID 1\) at pulse 9778"):
        build(kinematics=short)
    # A kinematics mapping without a type is the gantry, as before the two-link arm.
    config = DynamixelRobotConfig.model_validate(
        {"kinematics": {"x": {"id": 4, "metres_per_rad": 0.125}}})
    assert isinstance(config.kinematics, GantryConfig) and config.kinematics.x.id == 4


# --- the kit ------------------------------------------------------------------------------------


@pytest.mark.slow
def test_the_kit_applies_every_robot_check() -> None:
    # tests/test_bundled_conformance.py runs each of them on this spec, one test per check.
    names = {check.__name__ for check in checks_for(SPEC)}
    assert {"check_robot_contract", "check_robot_halt", "check_robot_stops_at_once",
            "check_robot_extremes", "check_robot_refuses_outside_workspace",
            "check_deterministic"} <= names


def test_refuses_outside_the_workspace_and_the_joint_limits(robot: DynamixelRobot) -> None:
    before = robot.bus.stats["instructions"] if robot.bus else 0
    with pytest.raises(ValueError, match="workspace"):
        robot.begin(line(0.5, 0.8))
    with pytest.raises(ValueError, match="limits"):
        robot.begin(ExploratoryMovement(np.array([0.1, 0.1]), np.array([0.2, 0.1]), 0.05,
                                        depth_m=0.2))
    assert robot.step() is None
    assert robot.bus is not None and robot.bus.stats["instructions"] == before  # nothing sent


# --- motion -------------------------------------------------------------------------------------


def test_a_movement_reaches_its_end_at_the_commanded_speed(robot: DynamixelRobot) -> None:
    movement = line(0.05, 0.35, speed=0.06)
    states = robot.execute(movement)
    t = np.array([s.timestamp_s for s in states])
    pos = np.vstack([s.position_m for s in states])
    np.testing.assert_allclose(np.diff(t), 1 / 50, rtol=1e-9)  # one control period per step
    assert np.linalg.norm(pos[0] - movement.start_m) < 0.002
    assert np.linalg.norm(pos[-1] - movement.end_m) <= 0.001 + 1e-9
    assert robot.halt_reason == ""
    # Cruising (past the servos' lag) at the commanded speed along x, y held.
    duration = movement.length_m / movement.speed_m_per_s
    cruise = (t > t[0] + 0.3) & (t < t[0] + duration - 0.1)
    speeds = np.array([s.speed_m_per_s for s in states])[cruise]
    assert np.mean(speeds) == pytest.approx(0.06, rel=0.02)
    assert np.max(np.abs(pos[:, 1] - 0.25)) < 0.001
    assert all(abs(s.depth_m - 0.03) < 0.001 for s in states)
    # It takes about length / speed, plus the lag to settle (bounded).
    assert duration <= t[-1] - t[0] + 1 / 50 < duration + 0.5
    # Timestamps are simulation time: the robot's FakeClock.
    assert isinstance(robot.clock, FakeClock) and t[-1] == robot.clock.now()
    assert robot.live is False
    assert robot.health.frames > len(states) and robot.health.timeouts == 0


def test_halt_stops_at_once_with_the_goal_at_the_present_position(
    robot: DynamixelRobot,
) -> None:
    robot.begin(line(0.05, 0.6))
    for _ in range(20):
        last = robot.step()
    assert last is not None
    robot.halt("interaction")
    assert robot.halt_reason == "interaction"
    bus = robot.bus
    assert bus is not None
    for servo_id in IDS:
        servo = bus.servo(servo_id)
        assert servo.get("Goal Position") == servo.get("Present Position")
    sent = bus.stats["instructions"]
    assert robot.step() is None and robot.step() is None
    assert bus.stats["instructions"] == sent  # no command after the halt
    assert np.array_equal(robot.state.position_m, last.position_m)
    assert torques(robot) == [1, 1, 1]  # halted, holding


def test_torque_follows_the_lifecycle() -> None:
    robot = build()
    try:
        robot.configure()
        bus = robot.bus
        assert bus is not None
        assert torques(robot) == [0, 0, 0]
        assert [bus.servo(i).get("Operating Mode") for i in IDS] == [3, 3, 3]
        assert bus.servo(3).get("Max Position Limit") == 4095
        robot.activate()
        assert torques(robot) == [1, 1, 1]
        robot.deactivate()
        assert robot.lifecycle_state is LifecycleState.INACTIVE
        assert torques(robot) == [0, 0, 0]
        robot.activate()
        assert torques(robot) == [1, 1, 1]
    finally:
        robot.close()
    assert robot.emulator is None and robot.lifecycle_state is LifecycleState.FINALIZED


def test_a_missing_servo_fails_configure_naming_it() -> None:
    robot = build(emulated_ids=(1, 3), reply_timeout_ms=REPLY_MS)
    try:
        with pytest.raises(DeviceError, match="servo 2 does not answer"):
            robot.configure()
        assert robot.lifecycle_state is LifecycleState.ERROR
        assert robot.health.timeouts >= 1
    finally:
        robot.close()


def test_a_wrong_model_fails_configure() -> None:
    robot = build()
    try:
        assert robot.bus is not None  # the emulated bus comes with the port, before configure
        robot.bus.servo(2).set("Model Number", 1060)  # an XL430-W250
        with pytest.raises(DeviceError, match=f"not an XM430-W350 \\({XM430_W350_MODEL_NUMBER}"):
            robot.configure()
    finally:
        robot.close()


def test_an_overload_mid_movement_is_counted_then_torque_off_and_device_error() -> None:
    # The emulated servos start at 2048 pulses; the transit to x = 0.05 takes ~3.8 s.
    robot = build(faults=[{"kind": "hardware_error", "at_s": 4.5, "params": {"id": 1}}],
                  reply_timeout_ms=REPLY_MS)
    robot.configure()
    robot.activate()
    try:
        robot.begin(line(0.05, 0.6))
        steps = 0
        while robot.clock.now() < 4.4:
            assert robot.step() is not None
            steps += 1
        assert steps > 10
        with pytest.raises(DeviceError, match="did not recover"):
            run_until_error(robot)
        # Found at the first step past the fault, then three recoveries' backoffs.
        backoffs = RECOVERY_BACKOFF_S * (1 + 2 + 4)
        assert 4.5 + backoffs <= robot.clock.now() <= 4.5 + 1 / 50 + backoffs + 1e-9
        assert robot.stats["hardware_errors"] >= 1
        assert robot.health.recoveries == robot.max_recoveries
        assert robot.lifecycle_state is LifecycleState.ERROR
        assert torques(robot) == [0, 0, 0]
        assert robot.bus is not None and robot.bus.servo(1).hardware_error
        assert robot.step() is None
    finally:
        robot.close()


def run_until_error(robot: DynamixelRobot) -> None:
    for _ in range(50):
        assert robot.step() is not None


def test_status_faults_are_counted_and_survived() -> None:
    faults = [
        {"kind": "no_reply", "at_s": 4.0, "params": {"id": 2}},
        {"kind": "bad_crc", "at_s": 4.2, "params": {"id": 1}},
        {"kind": "error_code", "at_s": 4.4, "params": {"id": 3, "error": 1}},
        {"kind": "sync_missing", "at_s": 4.6, "params": {"id": 2}},
        {"kind": "junk", "at_s": 4.8, "params": {"id": 1, "count": 6}},
    ]
    robot = build(faults=faults, reply_timeout_ms=REPLY_MS)
    robot.configure()
    robot.activate()
    try:
        movement = line(0.05, 0.15)
        states = robot.execute(movement)
        assert np.linalg.norm(states[-1].position_m - movement.end_m) <= 0.001 + 1e-9
        assert robot.health.timeouts >= 2 and robot.health.crc_errors >= 1
        assert robot.health.invalid_samples >= 1 and robot.stats["retries"] >= 4
        assert robot.health.recoveries == 0  # each survived by a retry
        assert robot.bus is not None
        assert {s.fault for s in robot.bus.sent if s.fault} >= {
            "no_reply", "bad_crc", "error_code", "sync_missing", "junk"}
    finally:
        robot.close()


def test_a_status_without_data_does_not_wedge_the_port(robot: DynamixelRobot) -> None:
    """The SDK's decoding raises IndexError on a status without data and leaves the port
    busy: the robot frees it and counts it as a failed attempt."""

    def crash(*_: Any) -> Any:
        robot._port.is_using = True
        raise IndexError("list index out of range")

    assert robot._call(crash) is None
    assert robot._port.is_using is False and robot.stats["sdk_index_errors"] == 1
    assert robot.execute(line(0.3, 0.32))  # the link still works


def test_same_seed_same_states_under_faults() -> None:
    """The states are a function of the seed; so are the faults the emulator injects. (How
    the SDK reports a fault, a timeout or a corrupt packet, may depend on real timing.)"""

    def run() -> tuple[np.ndarray, list[tuple[float, int, str]], dict[str, int]]:
        robot = make_component(SPEC, seed=3, config={"faults": FREQUENT,
                                                     "reply_timeout_ms": REPLY_MS},
                               interface=Robot)
        try:
            states = robot.execute(line(0.05, 0.45, speed=0.1))
            assert isinstance(robot, DynamixelRobot) and robot.bus is not None
            rows = np.array([[s.timestamp_s, *s.position_m, s.depth_m] for s in states])
            faults = [(s.due_s, s.servo_id, s.fault) for s in robot.bus.sent if s.fault]
            return rows, faults, robot.health.as_dict()
        finally:
            robot.close()

    first, faults, health = run()
    second, faults_again, _ = run()
    assert np.array_equal(first, second)
    assert faults == faults_again and len(faults) >= 3
    assert health["timeouts"] + health["crc_errors"] >= 3  # seen and survived
    assert health["recoveries"] == 0


FREQUENT = [{"kind": kind, "rate_hz": 1.0} for kind in ("no_reply", "bad_crc", "junk",
                                                         "sync_missing")]


def test_standard_faults_need_the_emulator() -> None:
    with pytest.raises(ValueError, match="emulated"):
        DynamixelRobotConfig(port="/dev/ttyUSB0", faults="standard")
    assert DynamixelRobotConfig(faults="standard").faults == "standard"


def test_the_torque_check_rides_on_the_state_read_in_one_bulk_read(robot: DynamixelRobot) -> None:
    """Issue 28 §4: every 0.25 s one BULK_READ (0x92) of Torque Enable..Present Position
    replaces the state's sync read and the torque check's: one round trip, not two."""
    assert robot.bus is not None
    seen: list[tuple[int, int]] = []
    dispatch = robot.bus._dispatch

    def logged(packet: Any, now_s: float) -> None:
        address = packet.params[0] | (packet.params[1] << 8) if len(packet.params) > 1 else -1
        seen.append((packet.instruction, address))
        dispatch(packet, now_s)

    robot.bus._dispatch = logged  # type: ignore[method-assign]
    checks, commands = robot.stats["torque_checks"], robot._commands
    robot.execute(line(0.05, 0.12, speed=0.06))
    bulk = [s for s in seen if s[0] == 0x92]
    sync_reads = [s for s in seen if s[0] == 0x82]
    assert len(bulk) == robot.stats["torque_checks"] - checks >= 4
    assert all(address != 64 for _, address in sync_reads)  # no separate torque read
    # One group read per commanded step (the transit to the start included).
    assert len(bulk) + len(sync_reads) == robot._commands - commands
