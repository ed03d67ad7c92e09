"""The ``dynamixel`` robot's transaction layer over ``dynamixel_sdk``: one bus transaction
(ping, write, GroupSyncWrite of the goals, GroupSyncRead of Present Current..Present
Position, and every 0.25 s one BULK_READ that adds the torque check to that read) with
bounded retries, then one recovery, counted in the device's health.

:class:`BusLink` is a :class:`~hapticframe.devices.DeviceLifecycle` mixin: the robot
provides ``config``, ``stats``, ``_port`` (the SDK's ``PortHandler``), ``_ph`` (its
``PacketHandler``) and ``_ids`` (the servos in joint order), and its ``on_recover``.
"""

from __future__ import annotations

import termios
from collections.abc import Callable
from typing import Any

import dynamixel_sdk  # type: ignore[import-untyped]
import numpy as np
import serial
from numpy.typing import NDArray

from hapticframe.devices import (
    DeviceError,
    DeviceLifecycle,
    DeviceModel,
    EmulatedPort,
    FakeClock,
    FaultSchedule,
)

from ._config import DynamixelRobotConfig
from ._control_table import XM430_W350, current_to_amps, to_signed
from ._emulator import DynamixelBus
from ._protocol import ERR_ALERT

__all__ = [
    "EMULATOR_LEAD_S",
    "RECOVERY_BACKOFF_S",
    "STANDARD_FAULTS",
    "BusError",
    "BusLink",
    "HardwareAlert",
]

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
    """The bus in simulation time: status packets emitted up to ``lead_s`` after the request.

    A replug of the emulated adapter (the harness's ``disconnect``) does not power-cycle the
    servos: on a U2D2 and a power hub they have their own supply (the bus's ``power_loss``
    fault is that case)."""

    def __init__(self, bus: DynamixelBus, lead_s: float) -> None:
        self.bus = bus
        self.lead_s = lead_s

    def receive(self, data: bytes, now_s: float) -> None:
        self.bus.receive(data, now_s)

    def emit(self, now_s: float) -> bytes:
        return self.bus.emit(now_s + self.lead_s)

    def power_cycle(self) -> None:
        self.bus.reconnect()


def _emulated_port(path: str, timeout_ms: float) -> Any:
    """A ``PortHandler`` whose reply timeout suits a pty on a loaded machine."""

    class EmulatedPort(dynamixel_sdk.PortHandler):
        def setPacketTimeout(self, packet_length: int) -> None:
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = self.tx_time_per_byte * packet_length + timeout_ms

    return EmulatedPort(path)


def emulated_bus_port(
    config: DynamixelRobotConfig, rng: np.random.Generator, ids: tuple[int, ...]
) -> tuple[EmulatedPort, DynamixelBus]:
    """The ``port: emulated`` link: the servos of ``config.emulated_ids`` (default ``ids``)
    on a :class:`DynamixelBus` behind a pseudo-terminal, on a fake clock (simulation time)
    that the robot moves by a control period per step. The pty is served by a thread:
    dynamixel-sdk blocks waiting for its replies."""
    fault_rng, bus_rng = rng.spawn(2)
    schedule = _schedule(config.faults, fault_rng)
    servo_ids = list(config.emulated_ids) if config.emulated_ids is not None else list(ids)
    bus = DynamixelBus(servo_ids, faults=schedule, rng=bus_rng,
                       time_constant_s=config.time_constant_s)
    port = EmulatedPort(_SteppedBus(bus, EMULATOR_LEAD_S), FakeClock(0.0), faults=schedule,
                        link_name="ttyDXL", thread=True)
    return port, bus


def _schedule(faults: Any, rng: np.random.Generator) -> FaultSchedule | None:
    if faults == "none":
        return None
    entries = STANDARD_FAULTS if faults == "standard" else faults
    return FaultSchedule.from_config([dict(e) for e in entries], rng)



class BusLink(DeviceLifecycle):
    """Bus transactions with bounded retries and recovery (a mixin of the robot)."""

    config: DynamixelRobotConfig
    stats: dict[str, int]
    _port: Any
    _ph: Any
    _ids: tuple[int, ...]

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
            raise DeviceError(f"robot {self.device_id!r}: {what} failed: {exc}",
                              device_id=self.device_id) from exc
        try:
            return attempt()
        except (BusError, OSError) as exc:
            raise DeviceError(f"robot {self.device_id!r}: {what} failed after a recovery: {exc}",
                              device_id=self.device_id) from exc

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
            f"robot {self.device_id!r}: servo {servo_id} does not answer on {self.config.port} "
            "(missing, wrong ID or baud rate, or unpowered)", device_id=self.device_id)

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

    def _group_read(self, start: int, length: int, what: str,
                    retries: int | None = None) -> list[bytes]:
        """One GroupSyncRead of ``length`` bytes from ``start`` on every servo (joint
        order), each status's error byte checked."""
        reader = dynamixel_sdk.GroupSyncRead(self._port, self._ph, start, length)
        for servo_id in self._ids:
            reader.addParam(servo_id)
        return self._read_statuses(reader.txPacket, length, what, retries)

    def _bulk_read(self, start: int, length: int, what: str,
                   retries: int | None = None) -> list[bytes]:
        """One BULK_READ (0x92) of ``length`` bytes from ``start`` on every servo (joint
        order). The entries could differ per servo; the driver uses one range that spans
        two reads (see :meth:`_sync_read_with_torque`)."""
        param = []
        for servo_id in self._ids:
            param += [servo_id, start & 0xFF, start >> 8, length & 0xFF, length >> 8]

        def request() -> int:
            comm: int = self._ph.bulkReadTx(self._port, param, len(param), False)
            return comm

        return self._read_statuses(request, length, what, retries)

    def _read_statuses(self, request: Callable[[], int], length: int, what: str,
                       retries: int | None) -> list[bytes]:
        """Send a group read's ``request`` and read each servo's status (joint order)."""

        def attempt() -> list[bytes]:
            comm = self._call(request)
            if comm != dynamixel_sdk.COMM_SUCCESS:
                self.health.timeouts += 1
                raise BusError(f"group read request: {comm}")
            raws = []
            for servo_id in self._ids:
                # The SDK's GroupSyncRead drops each status's error byte: read them here.
                result = self._call(self._ph.readRx, self._port, servo_id, length)
                if result is None:
                    raise BusError(f"servo {servo_id}: a status without data")
                data, comm, error = result
                if comm != dynamixel_sdk.COMM_SUCCESS:
                    self._count(comm)
                    raise BusError(f"servo {servo_id}: {self._ph.getTxRxResult(comm)}")
                self._check_status(servo_id, error)
                if len(data) != length:
                    self.health.invalid_samples += 1
                    raise BusError(f"servo {servo_id}: {len(data)} data bytes")
                raws.append(bytes(data))
            self.health.frames += 1
            return raws

        result: list[bytes] = self._transact(what, attempt, retries)
        return result

    def _sync_read(
        self, retries: int | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One GroupSyncRead of Present Current..Present Position: (pulses, amperes)."""
        raws = self._group_read(_READ_START, _READ_LENGTH, "the present positions' sync read",
                                retries)
        return self._state_from(raws)

    @staticmethod
    def _state_from(raws: list[bytes]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(pulses, amperes) from each servo's Present Current..Present Position bytes."""
        currents = [current_to_amps(int.from_bytes(raw[0:2], "little")) for raw in raws]
        positions = [to_signed(int.from_bytes(raw[6:10], "little"), 4) for raw in raws]
        return np.array(positions, dtype=np.float64), np.array(currents)

    def _sync_read_with_torque(
        self, retries: int | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`_sync_read` and the torque check in one round trip: one BULK_READ of
        Torque Enable..Present Position (72 bytes per servo) instead of two group reads. A
        servo whose torque went off behind the robot's back (it lost its supply) fails the
        recovery, so DeviceError."""
        start = _ADDR["Torque Enable"]
        raws = self._bulk_read(start, _READ_START + _READ_LENGTH - start,
                               "the present positions' and torque's bulk read", retries)
        self._torque_checked([raw[0] for raw in raws])
        return self._state_from([raw[_READ_START - start:] for raw in raws])

    def _torque_checked(self, torque_enable: list[int]) -> None:
        self.stats["torque_checks"] += 1
        for servo_id, value in zip(self._ids, torque_enable, strict=True):
            if value == 0:
                self.recover(HardwareAlert(f"servo {servo_id} lost its torque"))

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

