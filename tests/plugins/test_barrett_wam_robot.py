"""The ``barrett-wam`` robot on emulated pucks (python-can ``virtual``), in simulation time.

After configure (1 s of wake time) and activate, the emulated arm holds its fingertip over the
workspace's centre; the transit to LINE's start takes about 1.7 s and LINE itself 3 s, so a
fault at 4 s lands mid-movement (each test asserts it).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from hapticframe import RobotSpec
from hapticframe.devices import DeviceError, FakeClock, LifecycleState
from hapticframe.kinds import (
    BuildContext,
    EnvironmentCoupled,
    ExploratoryMovement,
    PhysicalTruth,
    Robot,
    RunOutcome,
)
from hapticframe.testing import (
    check_robot_refuses_outside_workspace,
    check_robot_stops_at_once,
    checks_for,
    make_component,
)
from hapticframe_barrett import Mode
from hapticframe_barrett._wam import BarrettWamRobot, EStop, NotFollowing
from hapticframe_barrett._wam_config import BarrettWamConfig

pytest.importorskip("can")

SPEC = RobotSpec(
    name="barrett-wam",
    summary="A Barrett WAM at trajectory level over the puck protocol (python-can).",
    config=BarrettWamConfig,
    factory="hapticframe_barrett._wam:BarrettWamRobot",
    capabilities=frozenset({"hardware"}),
)
FAULT_AT_S = 4.0


def build(seed: int = 0, **config: Any) -> BarrettWamRobot:
    return BarrettWamRobot(BarrettWamConfig(**config),
                           BuildContext(id="wam", rng=np.random.default_rng(seed)))


def line(x0: float = 0.30, x1: float = 0.45, y: float = 0.25, speed: float = 0.05,
         depth: float = 0.044) -> ExploratoryMovement:
    return ExploratoryMovement(np.array([x0, y]), np.array([x1, y]), speed, depth_m=depth)


@pytest.fixture
def up() -> Iterator:
    made: list[BarrettWamRobot] = []

    def make(seed: int = 0, **config: Any) -> BarrettWamRobot:
        robot = build(seed, **config)
        made.append(robot)
        robot.configure()
        robot.activate()
        return robot

    yield make
    for robot in made:
        emulator = robot.emulator
        robot.close()
        if emulator is not None:
            assert emulator.errors == [] and emulator.notifier_exception is None
            assert emulator.stats["mode_set_on_arm"] == 0  # MODE is the safety system's
        assert robot.lifecycle_state is LifecycleState.FINALIZED


def run(robot: BarrettWamRobot, movement: ExploratoryMovement, *, before_fault: bool = True
        ) -> list:
    robot.begin(movement)
    if before_fault:
        assert robot.clock.now() < FAULT_AT_S  # the fault comes mid-movement
    states = []
    while (state := robot.step()) is not None:
        states.append(state)
        assert len(states) < 2000
    return states


def run_to_error(robot: BarrettWamRobot) -> None:
    """Step until the robot raises (the test wraps this in pytest.raises)."""
    for _ in range(2000):
        if robot.step() is None:
            return


def counts_of(robot: BarrettWamRobot) -> list[int]:
    assert robot.emulator is not None
    return [robot.emulator.puck(n).counts() for n in robot.nodes]


# --- motion ---------------------------------------------------------------------------------


def test_a_straight_line_at_constant_speed_and_depth(up) -> None:
    robot = up()
    movement = line()
    states = run(robot, movement)
    t = np.array([s.timestamp_s for s in states])
    pos = np.vstack([s.position_m for s in states])
    np.testing.assert_allclose(np.diff(t), 0.01, rtol=1e-9)  # one control period per step
    assert np.linalg.norm(pos[0] - movement.start_m) < 0.001
    assert np.linalg.norm(pos[-1] - movement.end_m) <= 0.001
    assert robot.halt_reason == ""
    assert np.max(np.abs(pos[:, 1] - 0.25)) < 2e-4  # straight
    assert max(abs(s.depth_m - 0.044) for s in states) < 2e-4  # level
    speeds = np.array([s.speed_m_per_s for s in states[1:-1]])
    assert np.mean(speeds) == pytest.approx(0.05, rel=0.01)
    assert 3.0 - 1e-9 <= t[-1] - t[0] + 0.01 < 3.05
    assert isinstance(robot.clock, FakeClock) and t[-1] == robot.clock.now()
    assert robot.live is False and robot.health.faults() == {}
    assert robot.stats["mode_checks"] >= len(states)
    # The joints are read from the pucks: FK of the polled counts is the state.
    assert robot.transmission is not None
    q = robot.transmission.joints(counts_of(robot))
    np.testing.assert_allclose(robot.arm.forward(q)[:2], pos[-1], atol=1e-12)


def test_consecutive_movements_keep_time_increasing_and_lift_between(up) -> None:
    robot = up()
    first = run(robot, line(0.30, 0.34))
    assert robot.stats["targets_sent"] > 0
    second = run(robot, line(0.20, 0.25, y=0.35), before_fault=False)
    assert second[0].timestamp_s > first[-1].timestamp_s
    assert np.linalg.norm(second[-1].position_m - [0.25, 0.35]) <= 0.001


def test_a_seven_dof_arm_tracks_too(up) -> None:
    robot = up(arm="wam7")
    assert robot.nodes == (1, 2, 3, 4, 5, 6, 7)
    states = run(robot, line(0.30, 0.36))
    assert np.linalg.norm(states[-1].position_m - [0.36, 0.25]) <= 0.001
    assert max(abs(s.position_m[1] - 0.25) for s in states) < 2e-4


# --- safety ---------------------------------------------------------------------------------


def test_outside_the_workspace_or_the_joint_limits_is_refused_before_any_command(up) -> None:
    # J4 (the elbow) capped at 2.3 rad: the ends of a line along y = 0 fold the elbow to
    # about 2.2 rad, its middle, nearest the base, to 2.5 rad.
    robot = up(joint_limits_rad=((-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 2.3)))
    emulator = robot.emulator
    assert emulator is not None
    sent, frames = robot.stats["targets_sent"], emulator.stats["frames_in"]
    with pytest.raises(ValueError, match="workspace"):
        robot.begin(line(0.5, 0.8))
    with pytest.raises(ValueError, match=r"joint 4 at 2\.\d+ rad"):
        robot.begin(line(0.0, 0.75, y=0.0))
    with pytest.raises(ValueError, match="does not reach"):
        robot.begin(line(0.3, 0.4, depth=1.5))
    with pytest.raises(ValueError, match="rad/s"):
        robot.begin(line(0.3, 0.4, speed=5.0))
    assert robot.step() is None
    assert robot.stats["targets_sent"] == sent  # nothing was sent for any of them
    # Only position polls went out (no SET): the bus saw reads only.
    assert emulator.stats["frames_in"] - frames <= 8
    for end in (0.0, 0.75):  # each end alone is within the limits: the middle is not
        q = robot.arm.solve([end, 0.0, -0.044], robot.joints_rad, min_iterations=50)
        assert q.ok and robot.arm.within_limits(q.q)


def test_halt_holds_the_present_position_and_nothing_follows(up) -> None:
    robot = up()
    robot.begin(line())
    for _ in range(50):
        last = robot.step()
    assert last is not None
    robot.halt("interaction")
    assert robot.halt_reason == "interaction"
    assert robot.emulator is not None
    for node in robot.nodes:  # the target is the present position
        puck = robot.emulator.puck(node)
        assert puck.read("M") == puck.counts() and puck.mode == Mode.PID
    sent = robot.stats["targets_sent"]
    counts = counts_of(robot)
    robot.clock.advance(1.0)
    assert robot.step() is None and robot.step() is None
    assert robot.stats["targets_sent"] == sent  # no command after the halt
    assert counts_of(robot) == counts  # held
    assert np.array_equal(robot.state.position_m, last.position_m)


def test_the_kits_halt_checks_pass() -> None:
    check_robot_stops_at_once(SPEC)
    check_robot_refuses_outside_workspace(SPEC)


def test_activation_needs_the_operator_and_mode_is_never_set() -> None:
    robot = build(emulated_operator_activates=False)
    try:
        robot.configure()
        assert robot.lifecycle_state is LifecycleState.INACTIVE
        assert set(robot.host.tables) == {1, 2, 3, 4} if robot.host else False
        with pytest.raises(DeviceError, match="Shift-Activate"):
            robot.activate()
        assert robot.lifecycle_state is LifecycleState.ERROR
        assert robot.emulator is not None
        assert all(robot.emulator.puck(n).mode == Mode.IDLE for n in robot.nodes)
        assert robot.emulator.stats["mode_set_on_arm"] == 0
        with pytest.raises(DeviceError, match="configure and activate"):
            robot.begin(line())
    finally:
        robot.close()


def test_deactivate_holds_and_reactivates() -> None:
    robot = build()
    try:
        robot.configure()
        robot.activate()
        robot.deactivate()
        assert robot.lifecycle_state is LifecycleState.INACTIVE
        assert robot.emulator is not None
        assert all(robot.emulator.puck(n).mode == Mode.PID for n in robot.nodes)  # holding
        with pytest.raises(DeviceError):
            robot.begin(line())
        robot.activate()
        assert run(robot, line(0.30, 0.32))
    finally:
        robot.close()
    assert robot.emulator is None and robot.host is None


# --- faults ---------------------------------------------------------------------------------


def test_a_puck_that_never_wakes_fails_configure_naming_it() -> None:
    for absent in (0, 1):
        robot = build(faults=[{"kind": "never_wakes", "at_s": 0.0,
                               "params": {"node": 3, "absent": absent}}])
        try:
            with pytest.raises(DeviceError, match=r"WAM pucks \[3\] .* did not wake"):
                robot.configure()
            assert robot.lifecycle_state is LifecycleState.ERROR
            assert robot.clock.now() < 3.0  # bounded
        finally:
            robot.close()


@pytest.mark.parametrize(("fault", "counter"), [
    ({"kind": "late_reply", "params": {"delay_s": 1.5}}, "timeouts"),
    ({"kind": "malformed_reply", "params": {"how": "wrong_property"}}, "resyncs"),
    ({"kind": "malformed_reply", "params": {"how": "bit7"}}, "invalid_samples"),
    ({"kind": "duplicate_reply", "params": {"count": 3}}, "resyncs"),
    ({"kind": "missing_position", "params": {"node": 2}}, "dropped_samples"),
    ({"kind": "error_frame", "params": {"count": 4}}, "crc_errors"),
])
def test_reply_faults_are_survived_and_counted(up, fault, counter) -> None:
    robot = up(faults=[{**fault, "at_s": FAULT_AT_S}])
    movement = line()
    states = run(robot, movement)
    assert np.linalg.norm(states[-1].position_m - movement.end_m) <= 0.001
    assert robot.halt_reason == ""
    assert robot.health.as_dict()[counter] >= 1
    assert robot.health.recoveries == 0  # a retry was enough
    assert robot.emulator is not None and robot.emulator.faults is not None
    assert robot.emulator.faults.count(fault["kind"]) == 1
    if fault["kind"] == "missing_position":
        assert robot.stats["poll_retries"] == 1
    if fault["kind"] == "error_frame":
        assert robot.health.crc_errors == 4
    if fault["kind"] == "late_reply":  # a MODE read timed out, the second try answered
        assert robot.health.timeouts == 1 and robot.stats["mode_unread"] == 0
        assert robot.health.resyncs >= 1  # the late reply, discarded when it came
    t = np.array([s.timestamp_s for s in states])
    assert np.all(np.diff(t) > 0)


def test_an_estop_mid_motion_halts_with_a_device_error_and_nothing_more_is_sent(up) -> None:
    robot = up(faults=[{"kind": "estop", "at_s": FAULT_AT_S}])
    robot.begin(line())
    with pytest.raises(EStop, match="E-stop"):
        run_to_error(robot)
    assert FAULT_AT_S <= robot.clock.now() <= FAULT_AT_S + 0.011  # found in the same step
    assert robot.halt_reason == "device_error" and robot.stats["estops"] == 1
    sent = robot.stats["targets_sent"]
    assert robot.step() is None
    robot.halt("run")
    with pytest.raises(DeviceError):
        robot.begin(line(0.30, 0.31))
    robot.deactivate()
    assert robot.stats["targets_sent"] == sent  # no target after the stop
    assert robot.emulator is not None
    assert all(robot.emulator.puck(n).mode == Mode.IDLE for n in robot.nodes)


def test_an_estop_is_found_by_the_following_error_without_mode_checks(up) -> None:
    robot = up(faults=[{"kind": "estop", "at_s": FAULT_AT_S}], mode_check_every=0,
               following_error_rad=0.002)
    robot.begin(line(speed=0.1))
    with pytest.raises(NotFollowing, match="not following"):
        run_to_error(robot)
    assert robot.stats["mode_checks"] == 0 and robot.stats["not_following"] == 1
    sent = robot.stats["targets_sent"]
    assert robot.step() is None
    robot.close()
    assert robot.stats["targets_sent"] == sent


def test_a_short_bus_off_is_recovered(up) -> None:
    robot = up(faults=[{"kind": "bus_off", "at_s": FAULT_AT_S, "duration_s": 0.1}])
    movement = line()
    states = run(robot, movement)
    assert np.linalg.norm(states[-1].position_m - movement.end_m) <= 0.001
    health = robot.health
    assert health.stalls == 1 and health.reconnects == 1  # off, then restarted
    assert 1 <= health.recoveries <= robot.max_recoveries
    assert health.dropped_samples >= 4


def test_a_lasting_bus_off_is_a_bounded_device_error(up) -> None:
    robot = up(faults=[{"kind": "bus_off", "at_s": FAULT_AT_S, "duration_s": 30.0}])
    robot.begin(line())
    with pytest.raises(DeviceError, match="did not recover"):
        run_to_error(robot)
    assert robot.health.recoveries == robot.max_recoveries
    assert robot.clock.now() < FAULT_AT_S + 1.0  # bounded: backoffs 0.05 + 0.1 + 0.2 s
    assert robot.lifecycle_state is LifecycleState.ERROR
    assert robot.step() is None


def test_same_seed_same_states_under_random_faults() -> None:
    faults = [{"kind": kind, "rate_hz": 2.0} for kind in (
        "missing_position", "error_frame", "duplicate_reply", "malformed_reply")]

    def once() -> tuple[np.ndarray, list, dict]:
        robot = make_component(SPEC, seed=5, config={"faults": faults}, interface=Robot)
        try:
            states = robot.execute(line())
            rows = np.array([[s.timestamp_s, *s.position_m, s.depth_m] for s in states])
            assert isinstance(robot, BarrettWamRobot) and robot.emulator is not None
            assert robot.emulator.faults is not None
            injected = [(f.kind, f.time_s) for f in robot.emulator.faults.injected]
            return rows, injected, robot.health.as_dict()
        finally:
            robot.close()

    first, injected, health = once()
    second, again, _ = once()
    assert np.array_equal(first, second) and injected == again
    assert len(injected) >= 10
    assert health["dropped_samples"] >= 1 and health["crc_errors"] >= 1
    assert health["recoveries"] == 0


# --- config, coupling, metrics --------------------------------------------------------------


def test_config_refuses_torque_control_and_faults_on_a_real_bus() -> None:
    with pytest.raises(ValueError, match="experimental"):
        BarrettWamConfig(torque_control=True)
    with pytest.raises(ValueError, match="emulated"):
        BarrettWamConfig(channel="can0", faults="standard")
    with pytest.raises(ValueError, match="7 rows"):
        BarrettWamConfig(arm="wam7", joint_limits_rad=((-1, 1),) * 4)
    assert BarrettWamConfig(faults="standard").emulated


def test_a_missing_can_channel_is_a_clear_device_error() -> None:
    robot = build(channel="hapticframe-no-such-can", interface="no-such-interface")
    try:
        with pytest.raises(DeviceError, match="cannot open CAN channel"):
            robot.configure()
    finally:
        robot.close()


class _Environment:
    def __init__(self) -> None:
        self.asked: list[float] = []

    def physical_truth(self, timestamp_s: float) -> PhysicalTruth:
        self.asked.append(timestamp_s)
        zero = np.zeros(3)
        return PhysicalTruth(timestamp_s, zero, np.array([1.0, 0.0, 0.0, 0.0]), zero, zero,
                             zero, np.array([-2.0, 0.0, 1.0]), zero, 0.5)

    @property
    def truth_time_s(self) -> float:
        return self.asked[-1] if self.asked else 0.0


def test_couple_environment_records_joint_loads_only_when_emulated(up, tmp_path) -> None:
    with pytest.raises(ValueError, match="real WAM"):
        build(channel="can0").couple_environment(_Environment())
    robot = up()
    assert isinstance(robot, EnvironmentCoupled) and isinstance(robot, BarrettWamRobot)
    env = _Environment()
    robot.couple_environment(env)
    states = run(robot, line(0.30, 0.32))
    assert env.asked and env.asked[-1] == states[-1].timestamp_s
    jac, *_ = robot.arm.jacobian(robot.joints_rad)
    np.testing.assert_allclose(robot.load_torque_nm, jac.T @ [-2.0, 0.0, 1.0])
    metrics = robot.finalize(RunOutcome(tmp_path, None, (), {}, 0.0))["barrett_wam"]
    assert metrics["targets_sent"] == robot.stats["targets_sent"] > 0
    assert metrics["health"]["frames"] > 0 and "emulator" in metrics and "bus" in metrics


def test_the_kit_applies_every_robot_check() -> None:
    # tests/test_bundled_conformance.py runs each of them on this spec, one test per check.
    assert {"check_robot_contract", "check_robot_halt", "check_robot_stops_at_once",
            "check_robot_extremes", "check_robot_refuses_outside_workspace",
            "check_deterministic"} <= {check.__name__ for check in checks_for(SPEC)}
