"""The ``dynamixel`` robot: XM430-W350 servos driven by ``dynamixel_sdk`` moving the fingertip,
as a Cartesian gantry or a planar two-link arm, each on a vertical depth axis.

Each control step turns the next point of the straight movement (constant speed and depth)
into joint targets by inverse kinematics, streams them in one ``GroupSyncWrite``, and reads
Present Current and Present Position back in one ``GroupSyncRead``; forward kinematics of
the read positions gives the :class:`~hapticframe.kinds.RobotState`. ``begin`` checks the
whole line (not only its ends) against the mechanism's reach and joint limits; the move to
a movement's start is interpolated in joint space (within the limits wherever it goes).

``port: emulated`` runs a :class:`DynamixelBus` behind a :class:`PtyEmulator` that the
unmodified SDK opens by name. The SDK blocks waiting for replies, so the emulator serves the
pty in a thread (an :class:`EmulatedPort`); the bus's time is the port's fake clock, which
:meth:`DynamixelRobot.step` advances by one control period (and pumps once, so that the
servos move under the previous goal) before it writes the next goals. Servo dynamics
therefore run in simulation time and a run is deterministic. Status packets are emitted up
to :data:`EMULATOR_LEAD_S` of model time after their request (the return delay and the wire
take microseconds a frozen clock would never reach): the servos' state is read that much
later than the step's timestamp.
:meth:`DynamixelRobot.couple_environment` loads the emulated servos with a simulated
environment's force on the fingertip (``τ = −Jᵀ f``): Present Current follows it.
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Callable, Mapping
from typing import Any

import dynamixel_sdk  # type: ignore[import-untyped]
import numpy as np
from numpy.typing import NDArray

from hapticframe.devices import (
    Clock,
    DeviceError,
    DevicePort,
    EmulatedPort,
    PtyEmulator,
    SerialPort,
)
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    PhysicalTruthSource,
    Region,
    Robot,
    RobotState,
    RunOutcome,
)

from ._bus import (
    _ADDR,
    _LINK_ERRORS,
    _POSITION_MODE,
    EMULATOR_LEAD_S,
    RECOVERY_BACKOFF_S,
    STANDARD_FAULTS,
    BusError,
    BusLink,
    HardwareAlert,
    _emulated_port,
    emulated_bus_port,
)
from ._config import DynamixelRobotConfig, GantryConfig, TwoLinkConfig
from ._control_table import XM430_W350_MODEL_NUMBER
from ._emulator import DynamixelBus
from ._kinematics import Axis, Gantry, Joint, TwoLink, arm_inverse, line_problem

__all__ = [
    "EMULATOR_LEAD_S",
    "RECOVERY_BACKOFF_S",
    "STANDARD_FAULTS",
    "TORQUE_CHECK_PERIOD_S",
    "DynamixelRobot",
    "make_kinematics",
    "workspace_problem",
]

#: How often (robot clock) the torque of every servo is read back while moving: a servo
#: that lost its supply answers with its torque off and nothing else tells.
TORQUE_CHECK_PERIOD_S = 0.25
#: Points of the workspace checked at build time, at most (a grid over the rectangle).
_WORKSPACE_SAMPLES = 40_000


def make_kinematics(config: GantryConfig | TwoLinkConfig) -> Gantry | TwoLink:
    """The mechanism a ``kinematics`` config describes."""
    if isinstance(config, TwoLinkConfig):
        def joint(j: Any) -> Joint:
            return Joint(j.id, j.gear_ratio, j.offset_rad, j.min_pulse, j.max_pulse)

        z = config.z
        return TwoLink(joint(config.shoulder), joint(config.elbow),
                       Axis(z.id, z.metres_per_rad, z.offset_m, z.min_pulse, z.max_pulse),
                       config.l1_m, config.l2_m, config.base_m, config.elbow_side)
    return Gantry(*(Axis(a.id, a.metres_per_rad, a.offset_m, a.min_pulse, a.max_pulse)
                    for a in (config.x, config.y, config.z)))


def workspace_problem(kinematics: Gantry | TwoLink, region: Region,
                      depth_m: float) -> str | None:
    """Why the mechanism cannot reach all of ``region`` at ``depth_m``, or None. The
    gantry is checked at the corners (exact: its axes are independent); the arm's annulus
    exactly, its joint limits on a grid over the rectangle."""
    xs = (region.x_min_m, region.x_max_m)
    ys = (region.y_min_m, region.y_max_m)
    if isinstance(kinematics, TwoLink):
        base = np.asarray(kinematics.base_m)
        nearest = np.clip(base, [xs[0], ys[0]], [xs[1], ys[1]])
        corners = np.array([[x, y] for x in xs for y in ys])
        farthest = corners[np.argmax(np.linalg.norm(corners - base, axis=1))]
        try:  # the reach first (exact): the farthest and the nearest point
            arm_inverse([farthest, nearest], kinematics.l1_m, kinematics.l2_m,
                        kinematics.base_m)
        except ValueError as exc:
            return str(exc)
        width, height = region.size_m
        spacing = max(math.sqrt(width * height / _WORKSPACE_SAMPLES), 1e-4)
        gx = np.linspace(xs[0], xs[1], max(2, math.ceil(width / spacing) + 1))
        gy = np.linspace(ys[0], ys[1], max(2, math.ceil(height / spacing) + 1))
        mx, my = np.meshgrid(gx, gy)
        points = np.column_stack([mx.ravel(), my.ravel(), np.full(mx.size, depth_m)])
        return kinematics.problem(points)
    return kinematics.problem([[x, y, depth_m] for x in xs for y in ys])


class DynamixelRobot(Robot, BusLink):
    """Dynamixel servos raking the fingertip along straight lines: a Cartesian gantry or a
    planar two-link arm, each with a vertical depth axis (``config.kinematics``).

    The pose it records is forward kinematics of the positions read back; the heading is
    the movement's direction. Emulated, it is :class:`~hapticframe.kinds.EnvironmentCoupled`
    (:meth:`couple_environment`).

    Parameters
    ----------
    config : DynamixelRobotConfig
    context : BuildContext
        ``context.rng`` seeds the emulator's faults.

    Attributes
    ----------
    kinematics : Gantry or TwoLink
    clock : Clock
        The port's: simulation time when emulated, else the monotonic clock.
    port : DevicePort
        The serial device, or the emulated bus's pty (``port: emulated``).
    bus : DynamixelBus or None
        The emulated servos (``port: emulated``, after configure).
    stats : dict of str to int
        ``hardware_errors`` (alerts seen), ``status_errors`` (status packets with an error),
        ``sdk_index_errors`` (statuses without data that crashed the SDK's decoding),
        ``retries`` (transactions repeated), ``torque_checks`` (reads of every servo's
        Torque Enable, one per :data:`TORQUE_CHECK_PERIOD_S` of movement).
    present_current_a : (3,) float64
        The servos' Present Current at the latest step, in joint order.
    environment : PhysicalTruthSource or None
        What loads the emulated servos (:meth:`couple_environment`).
    """

    def __init__(self, config: DynamixelRobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.config: DynamixelRobotConfig = config
        self.max_recoveries = config.max_recoveries
        self.kinematics = make_kinematics(config.kinematics)
        self._ids = self.kinematics.ids
        self._workspace = config.workspace.to_region()
        region = self._workspace
        problem = workspace_problem(self.kinematics, region, config.depth_m)
        if problem is not None:
            raise ValueError(
                f"robot {context.id!r}: the workspace (x {region.x_min_m:g}...{region.x_max_m:g}"
                f" m, y {region.y_min_m:g}...{region.y_max_m:g} m at depth {config.depth_m:g} m)"
                f" is beyond the mechanism's reach or the servos' position limits: {problem}; "
                "shrink the workspace or change the kinematics"
            )
        self._dt = 1.0 / config.control_rate_hz
        self.live = not config.emulated
        self.port: DevicePort
        self.bus: DynamixelBus | None = None
        if config.emulated:
            self.port, self.bus = emulated_bus_port(config, context.rng, self._ids)
        else:
            self.port = SerialPort(config.port)
        self.clock: Clock = self.port.clock
        self._port: Any = None
        self._ph: Any = None
        self.stats = {"hardware_errors": 0, "status_errors": 0, "sdk_index_errors": 0,
                      "retries": 0, "torque_checks": 0}
        self._check_every = max(1, round(TORQUE_CHECK_PERIOD_S * config.control_rate_hz))
        self._commands = 0
        self.present_current_a = np.zeros(3)
        self.environment: PhysicalTruthSource | None = None
        self._joints: NDArray[np.float64] | None = None  # the latest measured pulses
        self._load_cache: tuple[float, NDArray[np.float64]] | None = None
        self._state = RobotState(0.0, region.center_m, 0.0, config.depth_m, 0.0)
        self._active = False
        self._halt_reason = ""
        self._pose = np.array([*region.center_m, config.depth_m])

    # --- Robot interface (the base checks depth and workspace, then calls _begin) ------------

    def _begin(self, movement: ExploratoryMovement, depth: float) -> None:
        self._active = False
        ends = np.vstack([movement.start_m, movement.end_m])
        poses = np.column_stack([ends, [depth, depth]])
        problem = line_problem(self.kinematics, poses[0], poses[1])
        if problem is not None:
            raise ValueError(
                f"robot {self.id!r}: the movement at depth {depth:g} m cannot be followed "
                f"within the servos' limits: {problem}")
        self._require_active()
        self._halt_reason = ""
        self._guarded(lambda: self._transit(poses[0]))
        self._start = poses[0]
        self._direction = np.append(_unit(movement), 0.0)
        self._length = movement.length_m
        self._speed = float(movement.speed_m_per_s)
        self._heading = movement.heading_rad
        self._travelled = 0.0
        self._extra = 0
        self._active = True

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        return self._guarded(self._step)

    def halt(self, reason: str) -> None:
        was_active = self._active
        self._active = False
        if was_active or not self._halt_reason:
            self._halt_reason = reason
        if self.lifecycle_state.value != "active" or self._port is None:
            return
        try:  # hold where the servos are: the goal becomes the present position
            positions, _ = self._sync_read(retries=0)
            self._sync_write(np.rint(positions).astype(int), retries=0)
            self._sync_read(retries=0)  # a reply after the write: the servos have the goal
        except Exception:
            self._torque_all(0)  # the bus misbehaves: stop by cutting the torque

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        return {"dynamixel": dict(self.stats)}

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    @property
    def emulator(self) -> PtyEmulator | None:
        """The emulated bus's pseudo-terminal (``port: emulated``, once configured)."""
        return self.port.emulator if isinstance(self.port, EmulatedPort) else None

    # --- the environment's load (EnvironmentCoupled) -------------------------------------------

    def couple_environment(self, environment: PhysicalTruthSource) -> None:
        """Load the emulated servos with ``environment``'s force on the fingertip.

        At model time ``t`` servo ``i`` carries ``τ_i = −(Jᵀ f)_i`` (N·m, the torque it
        exerts holding against the force), ``f = environment.physical_truth(t).force_n``
        (world frame: map x, y, z up) and ``J`` the Jacobian of the fingertip's position
        w.r.t. each servo's angle in radians at the latest measured joint positions (so the
        load is a function of model time and of what the robot read: deterministic). The
        bus turns it into Present Current with its torque constant.

        Raises
        ------
        ValueError
            When the robot drives real servos.
        """
        if not self.config.emulated:
            raise ValueError(
                f"robot {self.id!r} drives real servos on {self.config.port}: a simulated "
                "environment cannot load them (use port 'emulated' to couple it)")
        self.environment = environment
        self._load_cache = None
        if self.bus is not None:
            self._install_loads()

    def joint_torques_nm(self, force_n: Any, pulses: Any) -> NDArray[np.float64]:
        """``−Jᵀ f``: the torque each servo exerts (N·m, joint order) holding the fingertip
        against the world-frame force ``force_n`` (3,) at joint positions ``pulses``."""
        jac = self.kinematics.jacobian(np.asarray(pulses, dtype=np.float64))
        return np.asarray(-(jac.T @ np.asarray(force_n, dtype=np.float64)), dtype=np.float64)

    def _install_loads(self) -> None:
        assert self.bus is not None
        present = {servo.id for servo in self.bus.servos}
        for index, servo_id in enumerate(self._ids):
            if servo_id in present:
                self.bus.set_load(servo_id, functools.partial(self._servo_load_nm, index))

    def _servo_load_nm(self, index: int, t: float) -> float:
        return float(self._load_nm(t)[index])

    def _load_nm(self, t: float) -> NDArray[np.float64]:
        """The servos' loads at model time ``t`` (one physical_truth call per instant)."""
        cache = self._load_cache
        if cache is not None and cache[0] == t:
            return cache[1]
        assert self.environment is not None and self.bus is not None
        joints = self._joints
        if joints is None:  # before the first read: where the emulated shafts are
            positions = {servo.id: servo.position for servo in self.bus.servos}
            joints = np.array([positions.get(i, 2048.0) for i in self._ids])
        torques = self.joint_torques_nm(self.environment.physical_truth(t).force_n, joints)
        self._load_cache = (t, torques)
        return torques

    # --- motion ----------------------------------------------------------------------------

    def _require_active(self) -> None:
        if self.lifecycle_state.value != "active":
            raise DeviceError(
                f"robot {self.id!r} is {self.lifecycle_state.value}: configure and activate it "
                "before moving", device_id=self.id)

    def _guarded(self, fn: Callable[[], Any]) -> Any:
        """Run ``fn``; a DeviceError stops the robot (torque off, best effort) first."""
        try:
            return fn()
        except DeviceError:
            self._active = False
            self._halt_reason = "device_error"
            self._torque_all(0)
            raise

    def _tick(self, paced: bool) -> None:
        """One control period passes: simulation time advances (and the servos move under
        the previous goal), or a live robot waits when nobody else paces it."""
        until = self.clock.now() + self._dt
        self.port.wait_until(until)  # a port that owns time (the emulator's) moves it
        remaining = until - self.clock.now()
        if paced and remaining > 0:  # a live robot that nobody else paces waits itself
            self.clock.sleep(remaining)

    def _command(self, pulses: NDArray[np.float64], paced: bool) -> NDArray[np.float64]:
        """Command joint positions and read back the measured pose (one control period)."""
        self._tick(paced)
        # The line was checked in begin(); the clip only guards rounding between its samples.
        lo = np.array([s.min_pulse for s in self.kinematics.servos])
        hi = np.array([s.max_pulse for s in self.kinematics.servos])
        self._sync_write(np.clip(np.rint(pulses), lo, hi).astype(int))
        self._commands += 1
        if self._commands % self._check_every == 0:
            # The torque check rides on the state read: one BULK_READ, one round trip.
            positions, current = self._sync_read_with_torque()
        else:
            positions, current = self._sync_read()
        self._measured(positions)
        self.present_current_a = current
        return self._pose

    def _measured(self, positions: NDArray[np.float64]) -> None:
        self._joints = positions
        self._pose = self.kinematics.forward(positions)

    def _move_to(self, pose: NDArray[np.float64], paced: bool) -> NDArray[np.float64]:
        """Command ``pose`` (inverse kinematics) and read back the measured pose."""
        return self._command(self.kinematics.inverse(pose), paced)

    def _transit(self, target: NDArray[np.float64]) -> None:
        """Move to ``target`` at about the transit speed in joint space (within the joint
        limits all the way) and settle (no states recorded)."""
        assert self._joints is not None
        origin = self._joints.copy()
        goal = self.kinematics.inverse(target)
        fractions = np.linspace(0.0, 1.0, 65)[:, None]
        path = self.kinematics.forward(origin + fractions * (goal - origin))
        distance = float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
        steps = math.ceil(distance / (self.config.transit_speed_m_per_s * self._dt))
        for i in range(1, steps + 1):
            self._command(origin + (goal - origin) * (i / steps), paced=True)
        for _ in range(self.config.settle_steps):
            if np.linalg.norm(self._pose - target) <= self.config.tolerance_m:
                break
            self._command(goal, paced=True)
        self._publish(speed=0.0, heading=self._state.heading_rad)

    def _step(self) -> RobotState:
        self._travelled = min(self._travelled + self._speed * self._dt, self._length)
        previous = self._pose[:2].copy()
        target = self._start + self._direction * self._travelled
        measured = self._move_to(target, paced=False)
        speed = float(np.linalg.norm(measured[:2] - previous)) / self._dt
        state = self._publish(speed, self._heading)
        if self._travelled >= self._length:
            end = self._start + self._direction * self._length
            if np.linalg.norm(measured - end) <= self.config.tolerance_m:
                self._active = False
            else:
                self._extra += 1
                if self._extra >= self.config.settle_steps:
                    self._active = False
                    self._halt_reason = "not_settled"
        return state

    def _publish(self, speed: float, heading: float) -> RobotState:
        pose = self._pose
        self._state = RobotState(self.clock.now(), pose[:2].copy(), heading, float(pose[2]),
                                 speed)
        return self._state

    # --- lifecycle hooks ---------------------------------------------------------------------

    def on_configure(self) -> None:
        config = self.config
        path = self.port.path  # the device's, or the emulator's pty (started here)
        port = (_emulated_port(path, config.reply_timeout_ms) if config.emulated
                else dynamixel_sdk.PortHandler(path))
        self._ph = dynamixel_sdk.PacketHandler(2.0)
        try:
            opened = port.openPort()
        except _LINK_ERRORS as exc:
            raise DeviceError(f"robot {self.id!r}: cannot open {config.port}: {exc}",
                              device_id=self.id) from exc
        if not opened or not port.setBaudRate(config.baudrate):
            raise DeviceError(f"robot {self.id!r}: cannot open {config.port} at "
                              f"{config.baudrate} baud", device_id=self.id)
        self._port = port
        for servo_id in self._ids:
            model = self._ping(servo_id)
            if model != XM430_W350_MODEL_NUMBER:
                raise DeviceError(
                    f"robot {self.id!r}: servo {servo_id} on {config.port} is model {model}, "
                    f"not an XM430-W350 ({XM430_W350_MODEL_NUMBER})", device_id=self.id)
        for axis in self.kinematics.servos:
            self._write(axis.servo_id, "Torque Enable", 0, 1)
            self._write(axis.servo_id, "Operating Mode", _POSITION_MODE, 1)
            self._write(axis.servo_id, "Min Position Limit", axis.min_pulse, 4)
            self._write(axis.servo_id, "Max Position Limit", axis.max_pulse, 4)
        positions, _ = self._sync_read()
        self._measured(positions)
        self._publish(0.0, 0.0)

    def on_activate(self) -> None:
        positions, _ = self._sync_read()
        self._measured(positions)
        self._sync_write(np.rint(positions).astype(int))  # no jump when the torque comes on
        for servo_id in self._ids:
            self._write(servo_id, "Torque Enable", 1, 1)

    def on_deactivate(self) -> None:
        self._active = False
        self._torque_all(0)

    def on_cleanup(self) -> None:
        self._active = False
        if self._port is not None:
            with contextlib.suppress(*_LINK_ERRORS):
                self._port.closePort()
            self._port = None
        self.port.stop()

    def on_recover(self, error: Exception) -> None:
        """Wait a backoff on the robot's clock, reopen the port after a link error, ping every
        servo; fail while a servo has a latched hardware error or (when active) lost its
        torque (a power cycle): neither is undone behind the operator's back."""
        port = self._port
        if port is None:
            raise error
        backoff = RECOVERY_BACKOFF_S * 2 ** self.recovery_streak
        self.port.elapse(backoff)
        port.is_using = False
        if isinstance(error, OSError) or not port.is_open:
            with contextlib.suppress(*_LINK_ERRORS):
                port.closePort()
            self.health.reconnects += 1
            if not self._call(port.openPort):
                raise OSError(f"cannot reopen {self.config.port}")
            self._call(port.setBaudRate, self.config.baudrate)
        with contextlib.suppress(*_LINK_ERRORS):
            port.clearPort()
        active = self.lifecycle_state.value == "active"
        for servo_id in self._ids:
            result = self._call(self._ph.ping, port, servo_id)
            if result is None or result[1] != dynamixel_sdk.COMM_SUCCESS:
                raise BusError(f"servo {servo_id} does not answer ping")
            if result[0] != XM430_W350_MODEL_NUMBER:
                raise BusError(f"servo {servo_id} answers as model {result[0]}")
            for name, bad in (("Hardware Error Status", lambda v: v != 0),
                              ("Torque Enable", lambda v: active and v == 0)):
                result = self._call(self._ph.read1ByteTxRx, port, servo_id, _ADDR[name])
                if result is None or result[1] != dynamixel_sdk.COMM_SUCCESS:
                    raise BusError(f"servo {servo_id}: {name} unreadable")
                if bad(result[0]):
                    raise HardwareAlert(
                        f"servo {servo_id}: hardware error status 0x{result[0]:02x}, latched "
                        "until a reboot (torque off)" if name == "Hardware Error Status" else
                        f"servo {servo_id} lost its torque (power cycled?)")

    # --- the bus -------------------------------------------------------------------------------


def _unit(movement: ExploratoryMovement) -> NDArray[np.float64]:
    return np.array([math.cos(movement.heading_rad), math.sin(movement.heading_rad)])
