"""The BNO055 emulator: register file, modes, timing and the §2.4 faults, behind any transport.

:class:`Bno055Model` is a :class:`hapticframe.devices.DeviceModel`: a pure, clock-driven
protocol core. Put it behind a :class:`~hapticframe.devices.PtyEmulator` (a real serial
port path) or an :class:`~hapticframe.devices.EmulatedTransport` (in-process).

Physics (DESIGN §2): with the tool orientation R_wt of the truth source and the mount
misalignment R_ti, R_wi = R_wt R_ti and

- accelerometer (0x08) = R_wiᵀ (a_w + g e_z) + noise (specific force: +g along z at rest),
- linear acceleration (0x28) = R_wiᵀ a_w + the same noise, gravity (0x2E) = R_wiᵀ g e_z,
- gyroscope (0x14) = R_wiᵀ ω_w, quaternion (0x20) = world ← IMU,

quantised to the int16 registers. Outputs refresh at 100 Hz (the fusion rate): reads within
one 10 ms tick see the same values.

Faults (kinds of :class:`~hapticframe.devices.FaultEvent` this model applies; the byte-level
kinds ``drop_bytes``, ``garbage``, ``fragment``, ``stall`` and ``disconnect`` are applied by
the emulator harness):

=================  ===============================================================  ==========
kind               effect                                                           params
=================  ===============================================================  ==========
bus_overrun        the next ``count`` requests answer EE 07                         count
status             the next ``count`` requests answer EE ``code``                   code, count
no_reply           the next ``count`` requests get no answer at all                 count
partial_reply      the next read reply stops after ``keep`` data bytes              keep
wrong_length       the next read reply's length byte is off by ``delta``            delta
stale_bytes        the next read reply is preceded by the tail of the previous one  count
rx_stall           the next request's bytes come apart (>30 ms): EE 0A, 30 ms later
reset              the chip resets: 650 ms of silence, then CONFIG mode (zeros)
calib_drop         CALIB_STAT reads ``stat`` (default 0) for ``duration_s``         stat
bad_quaternion     the quaternion is scaled by ``scale`` for ``duration_s``          scale
bad_gravity        the gravity vector is scaled by ``scale`` for ``duration_s``      scale
=================  ===============================================================  ==========
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.devices import DeviceModel, EmulatedPort, FakeClock, FaultEvent, FaultSchedule
from hapticframe.geometry import (
    rotation_matrix_from_rpy_deg,
    rotation_matrix_from_wxyz,
    wxyz_from_rotation_matrix,
)

from ._protocol import (
    CHIP_ID_VALUE,
    DATA_LENGTH,
    DATA_START,
    MAX_PAYLOAD,
    READ_REPLY,
    REQUEST_START,
    SYS_TRIGGER_RESET,
    OperationMode,
    Register,
    Status,
    encode_data_block,
    encode_read_reply,
    encode_status,
    fusion_mode,
)

__all__ = [
    "GRAVITY_M_PER_S2",
    "MODEL_FAULT_KINDS",
    "Bno055Model",
    "ServedRead",
    "emulated_port",
    "standard_faults",
]

GRAVITY_M_PER_S2 = 9.80665
#: Fault kinds the model applies itself (the harness applies the byte-level ones).
MODEL_FAULT_KINDS = (
    "bus_overrun", "status", "no_reply", "partial_reply", "wrong_length", "stale_bytes",
    "rx_stall", "reset", "calib_drop", "bad_quaternion", "bad_gravity",
)
_REQUEST_FAULTS = ("no_reply", "rx_stall", "bus_overrun", "status")
_REPLY_FAULTS = ("partial_reply", "wrong_length", "stale_bytes")
#: Gap between received characters after which the chip drops a request (EE 0A).
CHARACTER_TIMEOUT_S = 0.030
RESET_SILENCE_S = 0.650
TO_CONFIG_S = 0.019
FROM_CONFIG_S = 0.007
FUSION_PERIOD_S = 0.01
_RESET_UNIT_SEL = 0x80  # datasheet reset value (Android orientation)


@dataclass(frozen=True)
class ServedRead:
    """One read of the data registers the model answered (for tests and diagnostics).

    ``corrupted`` names the value faults (``bad_quaternion``, ``bad_gravity``) applied, or
    is empty; ``frame_fault`` names the frame fault that spoiled the reply, if any.
    """

    time_s: float
    data: bytes
    corrupted: tuple[str, ...]
    frame_fault: str | None


def standard_faults() -> list[FaultEvent]:
    """The ``faults: standard`` schedule: every §2.4 fault, at rates a long run survives.

    Rates are per second of device time; a 100 s run sees each frame fault several times,
    a disconnect and a reset about once.
    """
    return [
        FaultEvent("bus_overrun", rate_hz=0.5, params={"count": 2}),
        FaultEvent("status", rate_hz=0.05, params={"code": int(Status.READ_FAIL)}),
        FaultEvent("no_reply", rate_hz=0.1),
        FaultEvent("partial_reply", rate_hz=0.1),
        FaultEvent("wrong_length", rate_hz=0.1),
        FaultEvent("stale_bytes", rate_hz=0.1),
        FaultEvent("rx_stall", rate_hz=0.1),
        FaultEvent("calib_drop", rate_hz=0.02, duration_s=2.0),
        FaultEvent("bad_quaternion", rate_hz=0.05, duration_s=0.05),
        FaultEvent("bad_gravity", rate_hz=0.05, duration_s=0.05),
        FaultEvent("reset", rate_hz=0.01),
        FaultEvent("garbage", rate_hz=0.1, params={"count": 3}),
        FaultEvent("fragment", rate_hz=0.2, duration_s=0.05),
        FaultEvent("stall", rate_hz=0.02, duration_s=0.05),
        FaultEvent("disconnect", rate_hz=0.01, duration_s=0.3),
    ]


TruthFunction = Callable[[float], Any]


class Bno055Model(DeviceModel):
    """A BNO055 on its UART, driven by a physical truth (at rest and level without one).

    Parameters
    ----------
    truth : callable, optional
        ``truth(t)`` → a :class:`hapticframe.kinds.PhysicalTruth`-like record (attributes
        ``orientation_wxyz``, ``linear_acceleration_m_per_s2``,
        ``angular_velocity_rad_per_s``) of the tool at device time ``t``.
    faults : FaultSchedule, optional
        The model's own fault kinds (:data:`MODEL_FAULT_KINDS`) are taken from it.
    rng : numpy.random.Generator, optional
        Accelerometer noise (required when ``accel_noise_std_m_per_s2`` > 0).
    mount_rpy_deg : (3,) array_like
        R_ti: the IMU's misalignment on the tool.
    accel_noise_std_m_per_s2 : float
    calibration_stat : int
        CALIB_STAT in a fusion mode (0xFF: everything calibrated).
    baudrate : int
        Sets how long a reply takes to send (10 bits per byte).
    response_delay_s : float
        Processing time before a reply starts.
    """

    def __init__(
        self,
        *,
        truth: TruthFunction | None = None,
        faults: FaultSchedule | None = None,
        rng: np.random.Generator | None = None,
        mount_rpy_deg: ArrayLike = (0.0, 0.0, 0.0),
        accel_noise_std_m_per_s2: float = 0.0,
        calibration_stat: int = 0xFF,
        baudrate: int = 115_200,
        response_delay_s: float = 0.0002,
    ) -> None:
        if accel_noise_std_m_per_s2 > 0 and rng is None:
            raise ValueError("accelerometer noise needs a generator (rng)")
        self.truth = truth
        self.faults = faults
        self._rng = rng
        self.mount_rotation = rotation_matrix_from_rpy_deg(mount_rpy_deg)
        self.accel_noise_std_m_per_s2 = float(accel_noise_std_m_per_s2)
        self.calibration_stat = calibration_stat & 0xFF
        self._byte_time_s = 10.0 / baudrate
        self._response_delay_s = response_delay_s
        #: Every read of the data registers answered, in order.
        self.served: list[ServedRead] = []
        #: Requests received (complete ones), for tests.
        self.requests = 0
        self._now = 0.0
        self._booting = False
        self._power_on()

    # --- state -----------------------------------------------------------------------
    def _power_on(self, silent_until_s: float = -math.inf) -> None:
        self.registers = bytearray(0x80)
        self.registers[Register.CHIP_ID] = CHIP_ID_VALUE
        self.registers[Register.UNIT_SEL] = _RESET_UNIT_SEL
        self.registers[Register.TEMP] = 25
        self._mode = int(OperationMode.CONFIG)
        self._mode_pending: tuple[float, int] | None = None
        self._rx = bytearray()
        self._rx_last_s = -math.inf
        self._outbox: list[tuple[float, bytes]] = []
        self._busy_until_s = -math.inf
        self._silent_until_s = silent_until_s
        self._pending = dict.fromkeys(_REQUEST_FAULTS + _REPLY_FAULTS, 0)
        self._status_code = int(Status.READ_FAIL)
        self._fault_params: dict[str, FaultEvent] = {}
        self._last_reply = b""
        self._tick: int | None = None
        self._tick_noise = np.zeros(3)

    def mode(self, now_s: float) -> int:
        """The operation mode in effect at ``now_s`` (a switch takes 7 or 19 ms)."""
        self._settle_mode(now_s)
        return self._mode

    def _settle_mode(self, now_s: float) -> None:
        if self._mode_pending is not None and now_s >= self._mode_pending[0]:
            self._mode = self._mode_pending[1]
            self._mode_pending = None

    def silent(self, now_s: float) -> bool:
        """True while the chip reboots after a reset (it neither hears nor answers)."""
        return now_s < self._silent_until_s

    def power_cycle(self) -> None:
        """A replug: registers back to their reset values; the chip boots for 650 ms."""
        self._power_on()
        self._booting = True

    def _reset(self, now_s: float) -> None:
        self._power_on(silent_until_s=now_s + RESET_SILENCE_S)

    # --- the DeviceModel interface -----------------------------------------------------
    def receive(self, data: bytes, now_s: float) -> None:
        """Bytes the host wrote, seen at ``now_s``."""
        self._advance(now_s)
        if self.silent(now_s):
            return
        if self._rx and now_s - self._rx_last_s > CHARACTER_TIMEOUT_S:
            self._character_timeout(self._rx_last_s + CHARACTER_TIMEOUT_S)
        self._rx.extend(data)
        self._rx_last_s = now_s
        self._parse(now_s)

    def emit(self, now_s: float) -> bytes:
        """The bytes the chip has finished sending by ``now_s``."""
        self._advance(now_s)
        if self._rx and now_s - self._rx_last_s > CHARACTER_TIMEOUT_S:
            self._character_timeout(self._rx_last_s + CHARACTER_TIMEOUT_S)
        out = bytearray()
        while self._outbox and self._outbox[0][0] <= now_s:
            out += self._outbox.pop(0)[1]
        return bytes(out)

    def _advance(self, now_s: float) -> None:
        self._now = now_s
        if self._booting:
            self._booting = False
            self._silent_until_s = now_s + RESET_SILENCE_S
        if self.faults is not None and self.faults.fires("reset", now_s) is not None:
            self._reset(now_s)
        self._settle_mode(now_s)

    def _character_timeout(self, at_s: float) -> None:
        self._rx.clear()
        self._queue(at_s, encode_status(Status.RECEIVE_CHARACTER_TIMEOUT))

    def _queue(self, now_s: float, reply: bytes) -> None:
        start = max(now_s + self._response_delay_s, self._busy_until_s)
        ready = start + len(reply) * self._byte_time_s
        self._busy_until_s = ready
        self._outbox.append((ready, reply))

    # --- requests ----------------------------------------------------------------------
    def _parse(self, now_s: float) -> None:
        while self._rx:
            if self._rx[0] != REQUEST_START:
                # A wrong start byte is dropped without an answer (datasheet §4.7).
                del self._rx[0]
                continue
            if len(self._rx) < 4:
                return
            operation, register, length = self._rx[1], self._rx[2], self._rx[3]
            size = 4 + (length if operation == 0x00 else 0)
            if len(self._rx) < size:
                return
            request = bytes(self._rx[:size])
            del self._rx[:size]
            self.requests += 1
            self._serve(request, operation, register, length, now_s)

    def _take_faults(self, now_s: float) -> None:
        if self.faults is None:
            return
        for kind in _REQUEST_FAULTS + _REPLY_FAULTS:
            while (event := self.faults.fires(kind, now_s)) is not None:
                count = int(event.params.get("count", 1)) if kind != "stale_bytes" else 1
                self._pending[kind] += max(count, 1)
                self._fault_params[kind] = event
                if kind == "status":
                    self._status_code = int(event.params.get("code", Status.READ_FAIL))

    def _serve(self, request: bytes, operation: int, register: int, length: int,
               now_s: float) -> None:
        self._take_faults(now_s)
        if self._pending["no_reply"]:
            self._pending["no_reply"] -= 1
            return
        if self._pending["rx_stall"]:
            self._pending["rx_stall"] -= 1
            self._queue(now_s + CHARACTER_TIMEOUT_S,
                        encode_status(Status.RECEIVE_CHARACTER_TIMEOUT))
            return
        if self._pending["bus_overrun"]:
            self._pending["bus_overrun"] -= 1
            self._queue(now_s, encode_status(Status.BUS_OVER_RUN_ERROR))
            return
        if self._pending["status"]:
            self._pending["status"] -= 1
            self._queue(now_s, encode_status(self._status_code))
            return
        if operation not in (0x00, 0x01):
            self._queue(now_s, encode_status(Status.WRONG_START_BYTE))
        elif length == 0:
            self._queue(now_s, encode_status(Status.MIN_LENGTH_ERROR))
        elif length > MAX_PAYLOAD:
            self._queue(now_s, encode_status(Status.MAX_LENGTH_ERROR))
        elif register + length > len(self.registers):
            self._queue(now_s, encode_status(Status.REGMAP_INVALID_ADDRESS))
        elif operation == 0x00:
            self._write(register, request[4:], now_s)
        else:
            self._read(register, length, now_s)

    def _write(self, register: int, data: bytes, now_s: float) -> None:
        if register == Register.SYS_TRIGGER and data[0] & SYS_TRIGGER_RESET:
            self._reset(now_s)  # never acknowledged in UART mode
            return
        config = self.mode(now_s) == OperationMode.CONFIG
        for address in range(register, register + len(data)):
            any_mode = address in (Register.PAGE_ID, Register.OPR_MODE, Register.PWR_MODE,
                                   Register.SYS_TRIGGER)
            writable = any_mode or (config and address >= Register.UNIT_SEL)
            if not writable:
                self._queue(now_s, encode_status(Status.REGMAP_WRITE_DISABLED))
                return
        for offset, value in enumerate(data):
            address = register + offset
            if address == Register.OPR_MODE:
                target = value & 0x0F
                if target != self._mode or self._mode_pending is not None:
                    delay = TO_CONFIG_S if target == OperationMode.CONFIG else FROM_CONFIG_S
                    self._mode_pending = (now_s + delay, target)
            self.registers[address] = value
        self._queue(now_s, encode_status(Status.WRITE_SUCCESS))

    def _read(self, register: int, length: int, now_s: float) -> None:
        image = bytearray(self.registers)
        end = register + length
        overlaps_data = register < DATA_START + DATA_LENGTH and end > DATA_START
        corrupted: tuple[str, ...] = ()
        if overlaps_data:
            block, corrupted = self.data_block(now_s)
            image[DATA_START : DATA_START + DATA_LENGTH] = block
        image[Register.OPR_MODE] = self._mode | (self.registers[Register.OPR_MODE] & 0xF0)
        data = bytes(image[register:end])
        reply = encode_read_reply(data)
        frame_fault = None
        if self._pending["partial_reply"]:
            self._pending["partial_reply"] -= 1
            event = self._fault_params.get("partial_reply")
            keep = int(event.params.get("keep", length // 2)) if event else length // 2
            reply = reply[: 2 + min(max(keep, 0), length - 1)]
            frame_fault = "partial_reply"
        elif self._pending["wrong_length"]:
            self._pending["wrong_length"] -= 1
            event = self._fault_params.get("wrong_length")
            delta = int(event.params.get("delta", 1)) if event else 1
            reply = bytes((READ_REPLY, (length + delta) & 0xFF)) + data
            frame_fault = "wrong_length"
        if self._pending["stale_bytes"]:
            self._pending["stale_bytes"] -= 1
            event = self._fault_params.get("stale_bytes")
            count = int(event.params.get("count", 5)) if event else 5
            previous = self._last_reply or bytes(count)
            # Only a tail: a whole stale reply would be indistinguishable from a fresh one.
            tail = previous[-min(count, len(previous) - 1) :] if len(previous) > 1 else previous
            reply = tail + reply
            frame_fault = frame_fault or "stale_bytes"
        self._last_reply = encode_read_reply(data)
        if overlaps_data:
            self.served.append(ServedRead(now_s, data, corrupted, frame_fault))
        self._queue(now_s, reply)

    # --- physics -----------------------------------------------------------------------
    def data_block(self, now_s: float) -> tuple[bytes, tuple[str, ...]]:
        """The data registers 0x08..0x35 at ``now_s``, and the value faults applied."""
        mode = self.mode(now_s)
        if mode == OperationMode.CONFIG:
            zeros = bytearray(DATA_LENGTH)  # fusion halted: every output reads zero
            zeros[Register.TEMP - DATA_START] = self.registers[Register.TEMP]
            zeros[Register.CALIB_STAT - DATA_START] = self._calibration(now_s, mode)
            return bytes(zeros), ()
        tick = math.floor(now_s / FUSION_PERIOD_S + 1e-9)
        t = tick * FUSION_PERIOD_S
        accel, lia, gravity, gyro, quat = self.ideal_values(t)
        if tick != self._tick:
            self._tick = tick
            if self.accel_noise_std_m_per_s2 > 0:
                assert self._rng is not None
                self._tick_noise = self._rng.normal(0.0, self.accel_noise_std_m_per_s2, 3)
        accel = accel + self._tick_noise
        lia = lia + self._tick_noise
        corrupted: list[str] = []
        if fusion_mode(mode):
            if self.faults is not None:
                event = self.faults.active("bad_quaternion", now_s)
                if event is not None:
                    quat = quat * float(event.params.get("scale", 0.9))
                    corrupted.append("bad_quaternion")
                event = self.faults.active("bad_gravity", now_s)
                if event is not None:
                    gravity = gravity * float(event.params.get("scale", 0.7))
                    corrupted.append("bad_gravity")
        else:
            lia = gravity = np.zeros(3)
            quat = np.zeros(4)
        block = encode_data_block(
            acceleration_m_per_s2=accel,
            angular_velocity_rad_per_s=gyro,
            orientation_wxyz=quat,
            linear_acceleration_m_per_s2=lia,
            gravity_m_per_s2=gravity,
            temperature_c=float(self.registers[Register.TEMP]),
            calibration_stat=self._calibration(now_s, mode),
            unit_sel=self.registers[Register.UNIT_SEL],
        )
        return block, tuple(corrupted)

    def _calibration(self, now_s: float, mode: int) -> int:
        stat = self.calibration_stat
        if not fusion_mode(mode):
            stat &= 0x3C  # no fusion and no magnetometer: system and mag levels 0
        if self.faults is not None:
            event = self.faults.active("calib_drop", now_s)
            if event is not None:
                stat = int(event.params.get("stat", 0)) & 0xFF
        return stat

    def ideal_values(
        self, t: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
               NDArray[np.float64], NDArray[np.float64]]:
        """Noise-free accelerometer, linear acceleration, gravity (m/s²), gyroscope
        (rad/s) and quaternion wxyz of the IMU at time ``t``, from the truth."""
        if self.truth is None:
            r_wt = np.eye(3)
            a_w = np.zeros(3)
            omega_w = np.zeros(3)
        else:
            state = self.truth(t)
            r_wt = rotation_matrix_from_wxyz(state.orientation_wxyz)
            a_w = np.asarray(state.linear_acceleration_m_per_s2, dtype=np.float64)
            omega_w = np.asarray(state.angular_velocity_rad_per_s, dtype=np.float64)
        r_wi = r_wt @ self.mount_rotation
        g_w = np.array([0.0, 0.0, GRAVITY_M_PER_S2])
        accel = r_wi.T @ (a_w + g_w)
        lia = r_wi.T @ a_w
        gravity = r_wi.T @ g_w
        gyro = r_wi.T @ omega_w
        return accel, lia, gravity, gyro, wxyz_from_rotation_matrix(r_wi)



def emulated_port(
    config: Any,
    rng: np.random.Generator,
    *,
    truth: Callable[[float], Any] | None,
    follow: Callable[[], float] | None,
    start_s: float,
    baudrate: int,
) -> EmulatedPort:
    """The ``port: emulated`` link: a :class:`Bno055Model` built from the sensor's config
    (a ``Bno055SensorConfig``) behind a pseudo-terminal, on a fake clock that starts at
    ``start_s`` and that each read moves to ``follow()`` (the robot's simulation time).
    ``rng`` seeds the faults, the noise and the byte faults' choices."""
    seeds = rng.integers(0, 2**63, size=3)
    entries = config.faults
    schedule: FaultSchedule | None = None
    if entries == "standard":
        schedule = FaultSchedule(standard_faults(), np.random.default_rng(int(seeds[0])))
    elif isinstance(entries, tuple) and entries:  # fault entries (FaultSetting)
        schedule = FaultSchedule.from_config(entries, np.random.default_rng(int(seeds[0])))
    model = Bno055Model(
        truth=truth,
        faults=schedule,
        rng=np.random.default_rng(int(seeds[1])),
        mount_rpy_deg=config.mount_rpy_deg,
        accel_noise_std_m_per_s2=config.accel_noise_std_m_per_s2,
        baudrate=baudrate,
    )
    return EmulatedPort(model, FakeClock(start_s), faults=schedule, follow=follow,
                        link_name="bno055", fragment_rng=np.random.default_rng(int(seeds[2])))
