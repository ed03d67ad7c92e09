"""The ``dynamixel`` robot: a Cartesian gantry of XM430-W350 servos driven by ``dynamixel_sdk``.

Each control step streams the goal positions of every axis in one ``GroupSyncWrite`` and
reads Present Current and Present Position back in one ``GroupSyncRead``; forward
kinematics turns them into the :class:`~hapticframe.kinds.RobotState`.

``port: emulated`` runs a :class:`DynamixelBus` behind a :class:`PtyEmulator` that the
unmodified SDK opens by name. The SDK blocks waiting for replies, so the emulator serves the
pty in a thread; the bus's time is a :class:`FakeClock` that :meth:`DynamixelRobot.step`
advances by one control period (and pumps once, so that the servos move under the previous
goal) before it writes the next goals. Servo dynamics therefore run in simulation time and a
run is deterministic. Status packets are emitted up to :data:`EMULATOR_LEAD_S` of model time
after their request (the return delay and the wire take microseconds a frozen clock would
never reach): the servos' state is read that much later than the step's timestamp.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import tempfile
import termios
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import dynamixel_sdk  # type: ignore[import-untyped]
import numpy as np
import serial
from numpy.typing import NDArray

from hapticframe.devices import (
    Clock,
    DeviceError,
    DeviceLifecycle,
    DeviceModel,
    FakeClock,
    FaultSchedule,
    MonotonicClock,
    PtyEmulator,
)
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Region,
    Robot,
    RobotState,
    RunOutcome,
)

from ._config import DynamixelRobotConfig
from ._control_table import XM430_W350, XM430_W350_MODEL_NUMBER, current_to_amps, to_signed
from ._emulator import DynamixelBus
from ._kinematics import Axis, Gantry
from ._protocol import ERR_ALERT

__all__ = ["EMULATOR_LEAD_S", "RECOVERY_BACKOFF_S", "STANDARD_FAULTS", "DynamixelRobot"]

#: Model time by which the emulated bus's status packets may follow their request.
EMULATOR_LEAD_S = 0.005
#: The first recovery waits this long (on the robot's clock), each next one twice as long.
RECOVERY_BACKOFF_S = 0.05
#: ``faults: standard``: rare status-packet faults, each survived by a retry.
STANDARD_FAULTS: tuple[dict[str, Any], ...] = (
    {"kind": "no_reply", "rate_hz": 0.05},
    {"kind": "bad_crc", "rate_hz": 0.05},
    {"kind": "junk", "rate_hz": 0.05},
    {"kind": "sync_missing", "rate_hz": 0.05},
)

_ADDR = {name: XM430_W350[name].address for name in (
    "Operating Mode", "Max Position Limit", "Min Position Limit", "Torque Enable",
    "Hardware Error Status", "Goal Position", "Present Current", "Present Position")}
#: One sync read covers Present Current (126, 2 bytes) to Present Position (132, 4 bytes).
_READ_START = _ADDR["Present Current"]
_READ_LENGTH = _ADDR["Present Position"] + 4 - _READ_START
_POSITION_MODE = 3
_LINK_ERRORS = (OSError, termios.error, serial.SerialException)


class BusError(RuntimeError):
    """A bus transaction failed (after its retries)."""


class HardwareAlert(RuntimeError):
    """A servo reports a latched hardware error (overload, overheating...)."""


class _SteppedBus(DeviceModel):
    """The bus in simulation time: status packets emitted up to ``lead_s`` after the request."""

    def __init__(self, bus: DynamixelBus, lead_s: float) -> None:
        self.bus = bus
        self.lead_s = lead_s

    def receive(self, data: bytes, now_s: float) -> None:
        self.bus.receive(data, now_s)

    def emit(self, now_s: float) -> bytes:
        return self.bus.emit(now_s + self.lead_s)

    def power_cycle(self) -> None:
        self.bus.power_cycle()


def _emulated_port(path: str, timeout_ms: float) -> Any:
    """A ``PortHandler`` whose reply timeout suits a pty on a loaded machine."""

    class EmulatedPort(dynamixel_sdk.PortHandler):
        def setPacketTimeout(self, packet_length: int) -> None:
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = self.tx_time_per_byte * packet_length + timeout_ms

    return EmulatedPort(path)


def _schedule(faults: Any, rng: np.random.Generator) -> FaultSchedule | None:
    if faults == "none":
        return None
    entries = STANDARD_FAULTS if faults == "standard" else faults
    return FaultSchedule.from_config([dict(e) for e in entries], rng)


class DynamixelRobot(Robot, DeviceLifecycle):
    """A Cartesian gantry of Dynamixel servos raking the fingertip along straight lines.

    Parameters
    ----------
    config : DynamixelRobotConfig
    context : BuildContext
        ``context.rng`` seeds the emulator's faults.

    Attributes
    ----------
    kinematics : Gantry
    clock : Clock
        A :class:`FakeClock` (simulation time) when emulated, else the monotonic clock.
    bus : DynamixelBus or None
        The emulated servos (``port: emulated``, after configure).
    stats : dict of str to int
        ``hardware_errors`` (alerts seen), ``status_errors`` (status packets with an error),
        ``sdk_index_errors`` (statuses without data that crashed the SDK's decoding),
        ``retries`` (transactions repeated).
    present_current_a : (3,) float64
        The servos' Present Current at the latest step.
    """

    def __init__(self, config: DynamixelRobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.config: DynamixelRobotConfig = config
        self.max_recoveries = config.max_recoveries
        k = config.kinematics
        self.kinematics = Gantry(*(
            Axis(a.id, a.metres_per_rad, a.offset_m, a.min_pulse, a.max_pulse)
            for a in (k.x, k.y, k.z)
        ))
        self._ids = self.kinematics.ids
        self._workspace = config.workspace.to_region()
        region = self._workspace
        corners = np.array([[x, y, config.depth_m]
                            for x in (region.x_min_m, region.x_max_m)
                            for y in (region.y_min_m, region.y_max_m)])
        if not np.all(self.kinematics.within_limits(self.kinematics.inverse(corners))):
            raise ValueError(
                f"robot {context.id!r}: the workspace (x {region.x_min_m:g}...{region.x_max_m:g}"
                f" m, y {region.y_min_m:g}...{region.y_max_m:g} m at depth {config.depth_m:g} m)"
                f" is beyond the servos' position limits (reach: {self.kinematics.reach()})"
            )
        self._dt = 1.0 / config.control_rate_hz
        self.live = not config.emulated
        self.clock: Clock = FakeClock(0.0) if config.emulated else MonotonicClock()
        self._rng = context.rng
        self.bus: DynamixelBus | None = None
        self.emulator: PtyEmulator | None = None
        self._link_dir: Path | None = None
        self._port: Any = None
        self._ph: Any = None
        self.stats = {"hardware_errors": 0, "status_errors": 0, "sdk_index_errors": 0,
                      "retries": 0}
        self.present_current_a = np.zeros(3)
        self._state = RobotState(0.0, region.center_m, 0.0, config.depth_m, 0.0)
        self._active = False
        self._halt_reason = ""
        self._pose = np.array([*region.center_m, config.depth_m])

    # --- Robot interface -----------------------------------------------------------------

    @property
    def control_rate_hz(self) -> float:
        return float(self.config.control_rate_hz)

    @property
    def state(self) -> RobotState:
        return self._state

    @property
    def halt_reason(self) -> str:
        return self._halt_reason

    @property
    def workspace(self) -> Region:
        return self._workspace

    def begin(self, movement: ExploratoryMovement) -> None:
        self._active = False
        depth = self.config.depth_m if movement.depth_m is None else float(movement.depth_m)
        if not (math.isfinite(depth) and depth > 0):
            raise ValueError(f"robot {self.id!r}: movement depth must be positive, got {depth}")
        region = self._workspace
        ends = np.vstack([movement.start_m, movement.end_m])
        outside = ends[~region.contains(ends)]
        if len(outside):
            x, y = outside[0].tolist()
            raise ValueError(
                f"robot {self.id!r}: the movement leaves the workspace at ({x:.4g}, {y:.4g}) m "
                f"(x {region.x_min_m:g}...{region.x_max_m:g} m, "
                f"y {region.y_min_m:g}...{region.y_max_m:g} m)"
            )
        poses = np.column_stack([ends, [depth, depth]])
        joints = self.kinematics.inverse(poses)
        if not np.all(self.kinematics.within_limits(joints)):
            raise ValueError(
                f"robot {self.id!r}: the movement at depth {depth:g} m needs joint positions "
                f"{np.rint(joints).astype(int).tolist()} beyond the servos' limits "
                f"{[(a.min_pulse, a.max_pulse) for a in self.kinematics.axes]}"
            )
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
        if isinstance(self.clock, FakeClock):
            self.clock.advance(self._dt)
            if self.emulator is not None:
                self.emulator.pump()
        elif paced:
            self.clock.sleep(self._dt)

    def _move_to(self, pose: NDArray[np.float64], paced: bool) -> NDArray[np.float64]:
        """Command ``pose`` and read back the measured pose (one control period)."""
        self._tick(paced)
        goal = np.rint(self.kinematics.inverse(pose)).astype(int)
        self._sync_write(goal)
        positions, current = self._sync_read()
        self.present_current_a = current
        measured = self.kinematics.forward(positions)
        self._pose = measured
        return measured

    def _transit(self, target: NDArray[np.float64]) -> None:
        """Move to ``target`` at the transit speed and settle (no states recorded)."""
        origin = self._pose.copy()
        distance = float(np.linalg.norm(target - origin))
        steps = math.ceil(distance / (self.config.transit_speed_m_per_s * self._dt))
        for i in range(1, steps + 1):
            self._move_to(origin + (target - origin) * (i / steps), paced=True)
        for _ in range(self.config.settle_steps):
            if np.linalg.norm(self._pose - target) <= self.config.tolerance_m:
                break
            self._move_to(target, paced=True)
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
        if config.emulated:
            self._start_emulator()
            assert self.emulator is not None
            port = _emulated_port(self.emulator.path, config.reply_timeout_ms)
        else:
            port = dynamixel_sdk.PortHandler(config.port)
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
        for axis in self.kinematics.axes:
            self._write(axis.servo_id, "Torque Enable", 0, 1)
            self._write(axis.servo_id, "Operating Mode", _POSITION_MODE, 1)
            self._write(axis.servo_id, "Min Position Limit", axis.min_pulse, 4)
            self._write(axis.servo_id, "Max Position Limit", axis.max_pulse, 4)
        positions, _ = self._sync_read()
        self._pose = self.kinematics.forward(positions)
        self._publish(0.0, 0.0)

    def on_activate(self) -> None:
        positions, _ = self._sync_read()
        self._pose = self.kinematics.forward(positions)
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
        if self.emulator is not None:
            self.emulator.stop()
            self.emulator = None
        if self._link_dir is not None:
            shutil.rmtree(self._link_dir, ignore_errors=True)
            self._link_dir = None

    def on_recover(self, error: Exception) -> None:
        """Wait a backoff on the robot's clock, reopen the port after a link error, ping every
        servo; fail while a servo has a latched hardware error or (when active) lost its
        torque (a power cycle): neither is undone behind the operator's back."""
        port = self._port
        if port is None:
            raise error
        backoff = RECOVERY_BACKOFF_S * 2 ** self.recovery_streak
        if isinstance(self.clock, FakeClock):
            self.clock.advance(backoff)
            if self.emulator is not None:
                self.emulator.pump()
        else:
            self.clock.sleep(backoff)
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

    def _start_emulator(self) -> None:
        config = self.config
        assert isinstance(self.clock, FakeClock)
        fault_rng, bus_rng = self._rng.spawn(2)
        schedule = _schedule(config.faults, fault_rng)
        ids = list(config.emulated_ids) if config.emulated_ids is not None else list(self._ids)
        self.bus = DynamixelBus(ids, faults=schedule, rng=bus_rng,
                                time_constant_s=config.time_constant_s)
        self._link_dir = Path(tempfile.mkdtemp(prefix="hapticframe-dxl-"))
        self.emulator = PtyEmulator(
            _SteppedBus(self.bus, EMULATOR_LEAD_S), clock=self.clock, faults=schedule,
            link_path=self._link_dir / "ttyDXL", thread=True,
        ).start()

    def _call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """One SDK call: a status without data crashes the SDK's decoding (IndexError) and
        leaves the port busy; the link's own errors become OSError."""
        try:
            return fn(*args)
        except IndexError:
            self._port.is_using = False
            self.stats["sdk_index_errors"] += 1
            return None
        except _LINK_ERRORS as exc:
            self._port.is_using = False
            raise OSError(f"the link to {self.config.port} failed: {exc}") from exc

    def _count(self, comm: int) -> None:
        if comm == dynamixel_sdk.COMM_RX_CORRUPT:
            self.health.crc_errors += 1
        else:
            self.health.timeouts += 1

    def _transact(self, what: str, attempt: Callable[[], Any], retries: int | None = None) -> Any:
        """``attempt()`` returns a result or raises BusError; retried, then recovered once."""
        tries = self.config.max_retries if retries is None else retries
        error: Exception = BusError(what)
        for i in range(tries + 1):
            if i:
                self.stats["retries"] += 1
            try:
                return attempt()
            except (BusError, OSError) as exc:
                error = exc
        try:
            self.recover(error)
        except DeviceError as exc:
            raise DeviceError(f"robot {self.id!r}: {what} failed: {exc}",
                              device_id=self.id) from exc
        try:
            return attempt()
        except (BusError, OSError) as exc:
            raise DeviceError(f"robot {self.id!r}: {what} failed after a recovery: {exc}",
                              device_id=self.id) from exc

    def _check_status(self, servo_id: int, error: int) -> None:
        if not error:
            return
        self.stats["status_errors"] += 1
        if error & ERR_ALERT:
            self.stats["hardware_errors"] += 1
            value = self._call(self._ph.read1ByteTxRx, self._port, servo_id,
                               _ADDR["Hardware Error Status"])
            bits = value[0] if value is not None else -1
            alert = HardwareAlert(f"servo {servo_id} raised the alert bit (hardware error "
                                  f"status {bits:#04x})")
            self.recover(alert)  # raises DeviceError unless the error has cleared
            return
        self.health.invalid_samples += 1
        raise BusError(f"servo {servo_id} answered with error {error:#04x}")

    def _ping(self, servo_id: int) -> int:
        def attempt() -> int:
            result = self._call(self._ph.ping, self._port, servo_id)
            if result is None:
                raise BusError("no ping data")
            model, comm, _ = result
            if comm != dynamixel_sdk.COMM_SUCCESS:
                self._count(comm)
                raise BusError(self._ph.getTxRxResult(comm))
            return int(model)

        for i in range(self.config.max_retries + 1):
            if i:
                self.stats["retries"] += 1
            try:
                return attempt()
            except BusError:
                continue
        raise DeviceError(
            f"robot {self.id!r}: servo {servo_id} does not answer on {self.config.port} "
            "(missing, wrong ID or baud rate, or unpowered)", device_id=self.id)

    def _write(self, servo_id: int, name: str, value: int, size: int) -> None:
        fn = {1: self._ph.write1ByteTxRx, 2: self._ph.write2ByteTxRx,
              4: self._ph.write4ByteTxRx}[size]

        def attempt() -> None:
            result = self._call(fn, self._port, servo_id, _ADDR[name], int(value))
            if result is None:
                raise BusError("no status")
            comm, error = result
            if comm != dynamixel_sdk.COMM_SUCCESS:
                self._count(comm)
                raise BusError(self._ph.getTxRxResult(comm))
            self._check_status(servo_id, error)

        self._transact(f"writing {name} = {value} to servo {servo_id}", attempt)

    def _sync_write(self, goals: NDArray[np.int_], retries: int | None = None) -> None:
        writer = dynamixel_sdk.GroupSyncWrite(self._port, self._ph, _ADDR["Goal Position"], 4)
        for servo_id, goal in zip(self._ids, goals.tolist(), strict=True):
            writer.addParam(servo_id, list(int(goal).to_bytes(4, "little", signed=True)))

        def attempt() -> None:
            comm = self._call(writer.txPacket)
            if comm != dynamixel_sdk.COMM_SUCCESS:
                self.health.timeouts += 1
                raise BusError(f"sync write: {comm}")

        self._transact("the goal positions' sync write", attempt, retries)

    def _sync_read(
        self, retries: int | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One GroupSyncRead of Present Current..Present Position: (pulses, amperes)."""
        reader = dynamixel_sdk.GroupSyncRead(self._port, self._ph, _READ_START, _READ_LENGTH)
        for servo_id in self._ids:
            reader.addParam(servo_id)

        def attempt() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
            comm = self._call(reader.txPacket)
            if comm != dynamixel_sdk.COMM_SUCCESS:
                self.health.timeouts += 1
                raise BusError(f"sync read request: {comm}")
            positions, currents = [], []
            for servo_id in self._ids:
                # The SDK's GroupSyncRead drops each status's error byte: read them here.
                result = self._call(self._ph.readRx, self._port, servo_id, _READ_LENGTH)
                if result is None:
                    raise BusError(f"servo {servo_id}: a status without data")
                data, comm, error = result
                if comm != dynamixel_sdk.COMM_SUCCESS:
                    self._count(comm)
                    raise BusError(f"servo {servo_id}: {self._ph.getTxRxResult(comm)}")
                self._check_status(servo_id, error)
                if len(data) != _READ_LENGTH:
                    self.health.invalid_samples += 1
                    raise BusError(f"servo {servo_id}: {len(data)} data bytes")
                raw = bytes(data)
                currents.append(current_to_amps(int.from_bytes(raw[0:2], "little")))
                positions.append(to_signed(int.from_bytes(raw[6:10], "little"), 4))
            self.health.frames += 1
            return np.array(positions, dtype=np.float64), np.array(currents)

        result: tuple[NDArray[np.float64], NDArray[np.float64]] = self._transact(
            "the present positions' sync read", attempt, retries)
        return result

    def _torque_all(self, value: int) -> None:
        """Best effort on every servo, each once (a failed one does not stop the others)."""
        if self._port is None or self._ph is None:
            return
        for servo_id in self._ids:
            try:
                self._call(self._ph.write1ByteTxRx, self._port, servo_id,
                           _ADDR["Torque Enable"], value)
            except Exception:
                continue


def _unit(movement: ExploratoryMovement) -> NDArray[np.float64]:
    return np.array([math.cos(movement.heading_rad), math.sin(movement.heading_rad)])
