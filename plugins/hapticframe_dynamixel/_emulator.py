"""An emulated Dynamixel Protocol 2.0 bus: XM430-W350 servos, their dynamics and faults.

:class:`DynamixelBus` is a :class:`hapticframe.devices.DeviceModel`: behind a
:class:`~hapticframe.devices.PtyEmulator` it is a pseudo-terminal that the unmodified
``dynamixel_sdk.PortHandler`` opens by name. Every servo answers PING, READ, WRITE,
SYNC_READ, SYNC_WRITE, BULK_READ and REBOOT as an XM430-W350 does (Status Return Level, the EEPROM
lock while torque is on, the position limits, the Alert bit), and moves in the model's clock
time: Present Position tracks Goal Position with a first-order lag, and an external load on
the servo (a function of time) raises Present Current; a current beyond the overload
threshold for a dwell time latches Hardware Error Status bit 5 (overload), which sets the
Alert bit and turns the torque off until REBOOT.

The model's own faults are the :data:`FAULT_KINDS` (from the notes' §3.4); ``disconnect``
and the other byte-level kinds are the harness's. A fault with ``params: {id: N}`` waits for
servo N's next status packet; without an id it takes the next status packet of any servo.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hapticframe.devices import DeviceModel, FaultEvent, FaultSchedule

from ._control_table import (
    EEPROM_END,
    PULSES_PER_REV,
    XM430_W350,
    ControlTable,
    amps_to_current,
    current_to_amps,
    encode,
    to_signed,
)
from ._protocol import (
    BROADCAST_ID,
    ERR_ACCESS,
    ERR_ALERT,
    ERR_DATA_LENGTH,
    ERR_DATA_RANGE,
    ERR_INSTRUCTION,
    ERR_RESULT_FAIL,
    INST_BULK_READ,
    INST_PING,
    INST_READ,
    INST_REBOOT,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    InstructionPacket,
    PacketParser,
    encode_status,
)

__all__ = [
    "FAULT_KINDS",
    "HW_ERROR_ELECTRICAL_SHOCK",
    "HW_ERROR_ENCODER",
    "HW_ERROR_INPUT_VOLTAGE",
    "HW_ERROR_OVERHEATING",
    "HW_ERROR_OVERLOAD",
    "DynamixelBus",
    "EmulatedServo",
    "SentStatus",
]

HW_ERROR_INPUT_VOLTAGE = 1 << 0
HW_ERROR_OVERHEATING = 1 << 2
HW_ERROR_ENCODER = 1 << 3
HW_ERROR_ELECTRICAL_SHOCK = 1 << 4
HW_ERROR_OVERLOAD = 1 << 5

#: The model's own fault kinds (the harness applies ``disconnect``, ``stall``, ``garbage``...).
FAULT_KINDS: Mapping[str, str] = {
    "no_reply": "one status packet is not sent",
    "bad_crc": "one status packet with a corrupted CRC",
    "error_code": "one status packet carries ERR params.error (1-7, default 1 result fail)",
    "late_reply": "one status packet is sent params.delay_s (default 0.5 s) late, past the "
    "SDK's timeout",
    "late_duplicate": "one status packet is sent again just before the next status packet "
    "on the bus (a stale answer to the next request)",
    "junk": "params.count (default 5) random bytes before one status packet; params.half=1: "
    "the first half of a status packet instead",
    "stuffing": "the servo's shaft is found at the multi-turn position params.position "
    "(default -131073: bytes FF FF FD FF, as after a wrap in extended position mode), so "
    "reading it needs byte stuffing",
    "sync_missing": "one servo (params.id, default the last listed) leaves one SYNC_READ "
    "unanswered",
    "hardware_error": "latch Hardware Error Status params.bit (default 5, overload) on a "
    "servo (params.id, default every servo); torque off if Shutdown has the bit",
    "current_spike": "Present Current raised by params.amps (default 2.0) for duration_s "
    "(a stall in sand); may trip the overload",
    "power_loss": "a servo (params.id, default every servo) loses its supply for an instant: "
    "RAM back to its defaults (torque off), EEPROM and shaft kept",
}

_STATUS_KINDS = ("no_reply", "bad_crc", "error_code", "late_reply", "late_duplicate", "junk")
_POSITION_MODES = (3, 4, 5)
_EXTENDED_LIMIT = 256 * PULSES_PER_REV


@dataclass(frozen=True)
class SentStatus:
    """One status packet the bus sent: when it was due, from which servo, with which ERR,
    and the fault that shaped it (empty when intact)."""

    due_s: float
    servo_id: int
    error: int
    fault: str = ""


@dataclass
class EmulatedServo:
    """One servo's memory and physical state (positions in pulses, floats)."""

    table: ControlTable
    memory: bytearray
    position: float = 0.0
    velocity: float = 0.0  # pulses/s
    current_a: float = 0.0
    load: Callable[[float], float] | None = None
    spike_a: float = 0.0
    overload_since_s: float | None = None
    updated_s: float | None = None
    reboots: int = 0

    def get(self, name: str) -> int:
        item = self.table[name]
        raw = int.from_bytes(self.memory[item.address : item.end], "little")
        return to_signed(raw, item.size) if item.signed else raw

    def set(self, name: str, value: int) -> None:
        item = self.table[name]
        self.memory[item.address : item.end] = encode(item, value)

    @property
    def id(self) -> int:
        return self.get("ID")

    @property
    def torque_enabled(self) -> bool:
        return self.get("Torque Enable") == 1

    @property
    def hardware_error(self) -> int:
        return self.get("Hardware Error Status")

    @property
    def present_current_a(self) -> float:
        return current_to_amps(self.get("Present Current"))


@dataclass
class _Out:
    due_s: float
    data: bytes
    order: int


@dataclass
class _Armed:
    kind: str
    event: FaultEvent
    servo_id: int | None


@dataclass
class _Bus:
    out: list[_Out] = field(default_factory=list)
    armed: list[_Armed] = field(default_factory=list)
    duplicate: bytes | None = None
    rx_time_s: float = -math.inf
    order: int = 0


class DynamixelBus(DeviceModel):
    """Several emulated XM430-W350 servos on one Protocol 2.0 bus.

    Parameters
    ----------
    ids : sequence of int
        The servos' IDs (each at its control table's defaults otherwise).
    faults : FaultSchedule, optional
        The schedule this model draws its :data:`FAULT_KINDS` from.
    rng : numpy.random.Generator, optional
        For junk bytes.
    time_constant_s : float
        The first-order lag of Present Position behind Goal Position (position modes).
    loads : mapping of int to callable, optional
        ``loads[id](t)`` → the external load on servo ``id`` at model time ``t`` (see
        ``load_unit``); set or change one later with :meth:`set_load`.
    load_unit : ``"nm"`` or ``"a"``
        Loads as torques (converted with ``torque_constant_nm_per_a``) or as currents.
    torque_constant_nm_per_a : float
        XM430-W350 at 12 V: 4.1 N·m stall at 2.3 A → about 1.78 N·m/A.
    overload_current_a : float or None
        The current beyond which the servo is overloaded; None: the Current Limit (reg 38).
    overload_dwell_s : float
        How long the current must stay beyond it before the overload latches.
    table : ControlTable
    initial_positions : mapping of int to int, optional
        Power-on shaft positions in pulses (default 2048, the middle).
    log_statuses : int
        How many status packets :attr:`sent` keeps.
    """

    def __init__(
        self,
        ids: Sequence[int] = (1,),
        *,
        faults: FaultSchedule | None = None,
        rng: np.random.Generator | None = None,
        time_constant_s: float = 0.05,
        loads: Mapping[int, Callable[[float], float]] | None = None,
        load_unit: str = "nm",
        torque_constant_nm_per_a: float = 1.78,
        overload_current_a: float | None = None,
        overload_dwell_s: float = 0.02,
        table: ControlTable = XM430_W350,
        initial_positions: Mapping[int, int] | None = None,
        log_statuses: int = 100_000,
    ) -> None:
        if load_unit not in ("nm", "a"):
            raise ValueError(f"load_unit must be 'nm' or 'a', got {load_unit!r}")
        if not time_constant_s > 0:
            raise ValueError("time_constant_s must be positive")
        if len(set(ids)) != len(ids) or any(not 0 <= i <= 252 for i in ids):
            raise ValueError(f"servo IDs must be distinct and in 0..252, got {list(ids)}")
        self.table = table
        self.faults = faults
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.time_constant_s = float(time_constant_s)
        self.load_unit = load_unit
        self.torque_constant_nm_per_a = float(torque_constant_nm_per_a)
        self.overload_current_a = overload_current_a
        self.overload_dwell_s = float(overload_dwell_s)
        self.parser = PacketParser(status=False)
        self.servos: list[EmulatedServo] = []
        positions = dict(initial_positions or {})
        for servo_id in ids:
            servo = EmulatedServo(table, table.defaults())
            servo.set("ID", servo_id)
            servo.position = float(positions.get(servo_id, PULSES_PER_REV // 2))
            servo.set("Goal Position", round(servo.position))
            servo.load = (loads or {}).get(servo_id)
            self._refresh(servo, 0.0)
            self.servos.append(servo)
        #: The status packets sent (or withheld by a fault), newest last, bounded.
        self.sent: deque[SentStatus] = deque(maxlen=log_statuses)
        self.stats: dict[str, int] = {
            "instructions": 0, "crc_errors": 0, "ignored": 0, "status_packets": 0,
            "overloads": 0, "reboots": 0, "power_cycles": 0, "reconnects": 0,
        }
        self._bus = _Bus()

    # -- public helpers ---------------------------------------------------------------------

    def servo(self, servo_id: int) -> EmulatedServo:
        """The servo with ID ``servo_id`` (KeyError if none)."""
        for servo in self.servos:
            if servo.id == servo_id:
                return servo
        raise KeyError(f"no servo with ID {servo_id} on the bus")

    def set_load(self, servo_id: int, load: Callable[[float], float] | None) -> None:
        """Put an external load (a function of model time, N·m or A) on a servo."""
        self.servo(servo_id).load = load

    # -- DeviceModel -------------------------------------------------------------------------

    def reconnect(self) -> None:
        """The host's adapter was unplugged and plugged in again while the servos kept
        their own supply: the bytes in flight are lost, the servos' state is kept."""
        self.parser.clear()
        self._bus = _Bus()
        self.stats["reconnects"] += 1

    def power_cycle(self) -> None:
        """Power off and on: RAM and hardware errors reset, EEPROM kept, shafts stay."""
        for servo in self.servos:
            self._reset_ram(servo)
        self.parser.clear()
        self._bus = _Bus()
        self.stats["power_cycles"] += 1

    def receive(self, data: bytes, now_s: float) -> None:
        if not data:
            return
        if now_s - self._bus.rx_time_s > 0.1:
            self.parser.clear()  # a torn packet from long ago: the servos' parsers time out
        self._bus.rx_time_s = now_s
        before = self.parser.counters.crc_errors
        packets = self.parser.feed(data)
        self.stats["crc_errors"] += self.parser.counters.crc_errors - before
        for packet in packets:
            assert isinstance(packet, InstructionPacket)
            self.stats["instructions"] += 1
            self._dispatch(packet, now_s)

    def emit(self, now_s: float) -> bytes:
        for servo in self.servos:
            self._advance(servo, now_s)
        bus = self._bus
        due = [o for o in bus.out if o.due_s <= now_s]
        if not due:
            return b""
        bus.out = [o for o in bus.out if o.due_s > now_s]
        due.sort(key=lambda o: (o.due_s, o.order))
        return b"".join(o.data for o in due)

    # -- dynamics ----------------------------------------------------------------------------

    def _overload_threshold_a(self, servo: EmulatedServo) -> float:
        if self.overload_current_a is not None:
            return float(self.overload_current_a)
        return current_to_amps(servo.get("Current Limit"))

    def _load_a(self, servo: EmulatedServo, t: float) -> float:
        if servo.load is None:
            return 0.0
        value = float(servo.load(t))
        return value if self.load_unit == "a" else value / self.torque_constant_nm_per_a

    def _advance(self, servo: EmulatedServo, now_s: float) -> None:
        """Move the servo's state to ``now_s`` (first-order tracking, load, overload)."""
        last = servo.updated_s
        if last is not None and now_s <= last:
            return
        dt = 0.0 if last is None else now_s - last
        servo.updated_s = now_s
        if self.faults is not None:
            spike = self.faults.active("current_spike", now_s)
            servo.spike_a = 0.0 if spike is None else float(spike.params.get("amps", 2.0))
        mode = servo.get("Operating Mode")
        if servo.torque_enabled and mode in _POSITION_MODES:
            goal = float(servo.get("Goal Position"))
            decay = math.exp(-dt / self.time_constant_s)
            servo.position = goal + (servo.position - goal) * decay
            servo.velocity = (goal - servo.position) / self.time_constant_s
        elif servo.torque_enabled and mode == 1:
            servo.velocity = servo.get("Goal Velocity") * 0.229 / 60.0 * PULSES_PER_REV
            servo.position += servo.velocity * dt
        else:
            servo.velocity = 0.0
        if servo.torque_enabled:
            servo.current_a = self._load_a(servo, now_s) + servo.spike_a
            if abs(servo.current_a) > self._overload_threshold_a(servo):
                if servo.overload_since_s is None:
                    servo.overload_since_s = now_s
                if now_s - servo.overload_since_s >= self.overload_dwell_s:
                    self._latch(servo, HW_ERROR_OVERLOAD)
                    self.stats["overloads"] += 1
            else:
                servo.overload_since_s = None
        else:
            servo.current_a = 0.0
            servo.overload_since_s = None
        self._refresh(servo, now_s)

    def _latch(self, servo: EmulatedServo, bit: int) -> None:
        servo.set("Hardware Error Status", servo.hardware_error | bit)
        if servo.get("Shutdown") & bit:
            servo.set("Torque Enable", 0)
            servo.current_a = 0.0
            servo.velocity = 0.0
            servo.overload_since_s = None

    def _refresh(self, servo: EmulatedServo, now_s: float) -> None:
        """Write the state into the read-only Present fields."""
        position = round(servo.position)
        rpm_units = round(servo.velocity * 60.0 / PULSES_PER_REV / 0.229)
        servo.set("Present Position", max(-(2**31), min(2**31 - 1, position)))
        servo.set("Present Velocity", max(-(2**31), min(2**31 - 1, rpm_units)))
        servo.set("Present Current", amps_to_current(servo.current_a))
        servo.set("Moving", int(abs(rpm_units) > servo.get("Moving Threshold")))
        servo.set("Realtime Tick", int(now_s * 1000.0) % 32768)
        servo.set("Position Trajectory", servo.get("Goal Position"))

    def _reset_ram(self, servo: EmulatedServo) -> None:
        defaults = self.table.defaults()
        servo.memory[EEPROM_END:] = defaults[EEPROM_END:]
        servo.set("Goal Position", max(-(2**31), min(2**31 - 1, round(servo.position))))
        servo.velocity = servo.current_a = 0.0
        servo.overload_since_s = None
        servo.reboots += 1
        self._refresh(servo, servo.updated_s or 0.0)

    # -- faults ------------------------------------------------------------------------------

    def _take(self, kind: str, servo_id: int | None, now_s: float) -> FaultEvent | None:
        """A fired fault of ``kind`` for this servo (``servo_id`` None: whatever its
        target), consumed."""
        if self.faults is None:
            return None
        armed = self._bus.armed
        while (event := self.faults.fires(kind, now_s)) is not None:
            target = event.params.get("id")
            armed.append(_Armed(kind, event, None if target is None else int(target)))
        for index, item in enumerate(armed):
            if item.kind == kind and (
                servo_id is None or item.servo_id is None or item.servo_id == servo_id
            ):
                del armed[index]
                return item.event
        return None

    def _instant_faults(self, now_s: float) -> None:
        if self.faults is None:
            return
        while (event := self.faults.fires("hardware_error", now_s)) is not None:
            bit = 1 << int(event.params.get("bit", 5))
            target = event.params.get("id")
            for servo in self.servos:
                if target is None or servo.id == int(target):
                    self._latch(servo, bit)
        while (event := self.faults.fires("power_loss", now_s)) is not None:
            target = event.params.get("id")
            for servo in self.servos:
                if target is None or servo.id == int(target):
                    self._reset_ram(servo)
            self.stats["power_cycles"] += 1
        while (event := self.faults.fires("stuffing", now_s)) is not None:
            target = event.params.get("id")
            value = int(event.params.get("position", -131073))
            for servo in self.servos:
                if target is None or servo.id == int(target):
                    servo.position = float(value)
                    servo.set("Goal Position", value)
                    self._refresh(servo, now_s)

    # -- instructions ------------------------------------------------------------------------

    def _dispatch(self, packet: InstructionPacket, now_s: float) -> None:
        for servo in self.servos:
            self._advance(servo, now_s)
        self._instant_faults(now_s)
        inst, params = packet.instruction, packet.params
        if packet.id == BROADCAST_ID:
            if inst == INST_PING:
                delay = 0.0
                for servo in sorted(self.servos, key=lambda s: s.id):
                    delay += self._return_delay_s(servo)
                    self._reply(servo, 0, self._ping_data(servo), now_s + delay, required=0)
                    delay += 14e-6 * 10  # 14 bytes at 1 Mbit/s
            elif inst == INST_SYNC_READ:
                self._sync_read(params, now_s)
            elif inst == INST_BULK_READ:
                self._bulk_read(params, now_s)
            elif inst == INST_SYNC_WRITE:
                self._sync_write(params, now_s)
            elif inst == INST_WRITE and len(params) >= 2:
                address = params[0] | (params[1] << 8)
                for servo in self.servos:
                    self._write(servo, address, params[2:])
            else:
                self.stats["ignored"] += 1
            return
        target = self._find(packet.id)
        if target is None:
            self.stats["ignored"] += 1
            return
        self._unicast(target, inst, params, now_s)

    def _unicast(self, servo: EmulatedServo, inst: int, params: bytes, now_s: float) -> None:
        due = now_s + self._return_delay_s(servo)
        if inst == INST_PING:
            self._reply(servo, 0, self._ping_data(servo), due, required=0)
        elif inst == INST_READ:
            if len(params) != 4:
                self._reply(servo, ERR_DATA_LENGTH, b"", due, required=1)
                return
            address = params[0] | (params[1] << 8)
            length = params[2] | (params[3] << 8)
            error, data = self._read(servo, address, length)
            self._reply(servo, error, data, due, required=1)
        elif inst == INST_WRITE:
            if len(params) < 3:
                self._reply(servo, ERR_DATA_LENGTH, b"", due, required=2)
                return
            address = params[0] | (params[1] << 8)
            error = self._write(servo, address, params[2:])
            self._reply(servo, error, b"", due, required=2)
        elif inst == INST_REBOOT:
            self._reply(servo, 0, b"", due, required=2)
            self._reset_ram(servo)
            self.stats["reboots"] += 1
        else:
            self._reply(servo, ERR_INSTRUCTION, b"", due, required=2)

    def _find(self, servo_id: int) -> EmulatedServo | None:
        for servo in self.servos:
            if servo.id == servo_id:
                return servo
        return None

    @staticmethod
    def _return_delay_s(servo: EmulatedServo) -> float:
        return servo.get("Return Delay Time") * 2e-6

    @staticmethod
    def _ping_data(servo: EmulatedServo) -> bytes:
        return servo.get("Model Number").to_bytes(2, "little") + bytes(
            (servo.get("Firmware Version"),)
        )

    def _read(self, servo: EmulatedServo, address: int, length: int) -> tuple[int, bytes]:
        if length == 0:
            return ERR_DATA_LENGTH, b""
        if address + length > len(servo.memory):
            return ERR_ACCESS, b""
        return 0, bytes(servo.memory[address : address + length])

    def _write(self, servo: EmulatedServo, address: int, data: bytes) -> int:
        """Apply a WRITE; the ERR number (0: done). Nothing is written on an error."""
        end = address + len(data)
        if not data:
            return ERR_DATA_LENGTH
        if end > len(servo.memory):
            return ERR_ACCESS
        touched = []
        for a in range(address, end):
            item = self.table.at(a)
            if item is None:
                continue
            if not item.writable:
                return ERR_ACCESS
            if item.area == "EEPROM" and servo.torque_enabled:
                return ERR_ACCESS
            if item not in touched:
                touched.append(item)
        image = bytearray(servo.memory)
        image[address:end] = data
        for item in touched:
            if item.address < address or item.end > end:
                return ERR_DATA_LENGTH  # a multi-byte item written in part
        for item in touched:
            raw = int.from_bytes(image[item.address : item.end], "little")
            value = to_signed(raw, item.size) if item.signed else raw
            error = self._check_value(servo, item.name, value, image)
            if error:
                return error
        if "Torque Enable" in (item.name for item in touched):
            if image[self.table["Torque Enable"].address] and servo.hardware_error:
                return ERR_RESULT_FAIL  # torque stays off until REBOOT
        servo.memory[address:end] = data
        return 0

    def _check_value(self, servo: EmulatedServo, name: str, value: int,
                     image: bytearray) -> int:
        def field_value(field_name: str) -> int:
            item = self.table[field_name]
            raw = int.from_bytes(image[item.address : item.end], "little")
            return to_signed(raw, item.size) if item.signed else raw

        if name == "Goal Position":
            mode = field_value("Operating Mode")
            if mode == 3:
                low, high = field_value("Min Position Limit"), field_value("Max Position Limit")
            else:
                low, high = -_EXTENDED_LIMIT + 1, _EXTENDED_LIMIT - 1
            if not low <= value <= high:
                return ERR_DATA_RANGE
        elif name == "Operating Mode" and value not in (0, 1, 3, 4, 5, 16):
            return ERR_DATA_RANGE
        elif name == "Torque Enable" and value not in (0, 1):
            return ERR_DATA_RANGE
        elif name == "Status Return Level" and value not in (0, 1, 2):
            return ERR_DATA_RANGE
        elif name == "ID" and (value > 252 or (value != servo.id and self._find(value))):
            return ERR_DATA_RANGE
        elif name == "Goal Current" and abs(value) > field_value("Current Limit"):
            return ERR_DATA_RANGE
        elif name in ("Max Position Limit", "Min Position Limit") and not 0 <= value <= 4095:
            return ERR_DATA_RANGE
        return 0

    def _sync_read(self, params: bytes, now_s: float) -> None:
        if len(params) < 5:
            return
        address = params[0] | (params[1] << 8)
        length = params[2] | (params[3] << 8)
        ids = list(params[4:])
        missing: int | None = None
        event = self._take("sync_missing", None, now_s)
        if event is not None:
            missing = int(event.params.get("id", ids[-1]))
        due = now_s
        for servo_id in ids:
            servo = self._find(servo_id)
            if servo is None:
                continue
            due += self._return_delay_s(servo)
            if servo_id == missing:
                self.sent.append(SentStatus(due, servo_id, 0, "sync_missing"))
                continue
            error, data = self._read(servo, address, length)
            self._reply(servo, error, data, due, required=1)
            due += (11 + length) * 10e-6  # the previous status on the wire at 1 Mbit/s

    def _bulk_read(self, params: bytes, now_s: float) -> None:
        """BULK_READ: (id, address, length) per servo; each answers in the listed order,
        after the previous status is on the wire."""
        if not params or len(params) % 5:
            self.stats["ignored"] += 1
            return
        entries = [(params[k], params[k + 1] | (params[k + 2] << 8),
                    params[k + 3] | (params[k + 4] << 8)) for k in range(0, len(params), 5)]
        if len({servo_id for servo_id, _, _ in entries}) != len(entries):
            self.stats["ignored"] += 1  # an ID listed twice: the packet is invalid
            return
        due = now_s
        for servo_id, address, length in entries:
            servo = self._find(servo_id)
            if servo is None:
                continue
            due += self._return_delay_s(servo)
            error, data = self._read(servo, address, length)
            self._reply(servo, error, data, due, required=1)
            due += (11 + length) * 10e-6  # the previous status on the wire at 1 Mbit/s

    def _sync_write(self, params: bytes, now_s: float) -> None:
        if len(params) < 4:
            return
        address = params[0] | (params[1] << 8)
        length = params[2] | (params[3] << 8)
        body = params[4:]
        step = length + 1
        if length == 0 or len(body) % step:
            self.stats["ignored"] += 1
            return
        for offset in range(0, len(body), step):
            servo = self._find(body[offset])
            if servo is not None:
                self._write(servo, address, body[offset + 1 : offset + step])

    # -- status packets ----------------------------------------------------------------------

    def _reply(self, servo: EmulatedServo, error: int, data: bytes, due_s: float, *,
               required: int) -> None:
        """Queue a status packet if the Status Return Level allows (``required`` = the
        level this instruction needs: 0 ping, 1 read, 2 everything), with faults applied."""
        if servo.get("Status Return Level") < required:
            return
        if servo.hardware_error:
            error |= ERR_ALERT
        servo_id = servo.id
        now_s = due_s
        fault = ""
        if self._take("no_reply", servo_id, now_s) is not None:
            self.sent.append(SentStatus(due_s, servo_id, error, "no_reply"))
            return
        if (event := self._take("error_code", servo_id, now_s)) is not None:
            error = (error & ERR_ALERT) | (int(event.params.get("error", ERR_RESULT_FAIL)) & 0x7F)
            data, fault = b"", "error_code"
        packet = encode_status(servo_id, error, data)
        if self._take("bad_crc", servo_id, now_s) is not None:
            packet = packet[:-1] + bytes((packet[-1] ^ 0x5A,))
            fault = "bad_crc"
        if (event := self._take("junk", servo_id, now_s)) is not None:
            if int(event.params.get("half", 0)):
                junk = packet[: max(8, len(packet) // 2)]
            else:
                count = int(event.params.get("count", 5))
                # No 0xFF: random junk that forms a header by chance is a different fault.
                junk = self.rng.integers(0, 0xFF, size=count, dtype=np.uint8).tobytes()
            packet = junk + packet
            fault = fault or "junk"
        if (event := self._take("late_reply", servo_id, now_s)) is not None:
            due_s += float(event.params.get("delay_s", 0.5))
            fault = fault or "late_reply"
        bus = self._bus
        if bus.duplicate is not None:
            self._queue(bus.duplicate, due_s)
            bus.duplicate = None
        if self._take("late_duplicate", servo_id, now_s) is not None:
            bus.duplicate = packet
            fault = fault or "late_duplicate"
        self._queue(packet, due_s)
        self.stats["status_packets"] += 1
        self.sent.append(SentStatus(due_s, servo_id, error, fault))

    def _queue(self, data: bytes, due_s: float) -> None:
        bus = self._bus
        bus.order += 1
        bus.out.append(_Out(due_s, data, bus.order))

    def describe(self) -> dict[int, dict[str, Any]]:
        """A summary for logs: servos, positions, torque, hardware errors."""
        return {
            servo.id: {
                "position": servo.get("Present Position"),
                "torque": servo.torque_enabled,
                "hardware_error": servo.hardware_error,
            }
            for servo in self.servos
        }
