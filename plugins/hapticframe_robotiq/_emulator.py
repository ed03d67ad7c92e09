"""An emulated Robotiq FT 300: its protocol core, physics and fault matrix.

:class:`Ft300Model` is a :class:`hapticframe.devices.DeviceModel`: put it behind a
:class:`~hapticframe.devices.PtyEmulator` (a real pseudo-terminal that any serial library
opens) or an :class:`~hapticframe.devices.EmulatedTransport` (in-process), paced by a clock.
In Modbus mode it answers function 03 on registers 180-185, 500-502 and 510-514 and function
16 on register 410; writing 0x0200 there starts the 100 Hz stream, which stops when the host
sends a run of 0xFF bytes (the jam).

Each frame is computed from the robot's physical truth at the frame's time (see
:class:`Ft300Physics`), or a sensor at rest without a robot. The protocol faults of the
fault matrix are the :data:`FAULT_KINDS`; byte-level faults (``stall``, ``drop_bytes``,
``garbage``, ``fragment``, ``disconnect``) are applied by the emulator harness to the bytes
the model emits. Every frame it sends is logged in :attr:`Ft300Model.sent`, with whether
it left intact, so tests compare what a driver delivered with what the device measured.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from hapticframe.devices import (
    DeviceModel,
    EmulatedPort,
    FakeClock,
    FaultEvent,
    FaultSchedule,
    append_crc16,
)
from hapticframe.geometry import rotation_matrix_from_wxyz

from ._protocol import (
    FUNCTION_READ_HOLDING,
    FUNCTION_WRITE_MULTIPLE,
    REGISTER_FIRMWARE,
    REGISTER_FORCE_TORQUE,
    REGISTER_OUTPUT_MODE,
    REGISTER_PRODUCTION_YEAR,
    REGISTER_SERIAL_NUMBER,
    STREAM_FRAME_LENGTH,
    STREAM_HEADER,
    STREAM_MODE_VALUE,
    ProtocolError,
    decode_stream_values,
    encode_exception_reply,
    encode_firmware,
    encode_read_reply,
    encode_serial_number,
    encode_stream_frame,
    encode_write_reply,
    parse_request,
    quantise,
)

__all__ = [
    "FAULT_KINDS",
    "FRAME_PERIOD_S",
    "STANDARD_FAULTS",
    "STANDARD_GRAVITY_M_PER_S2",
    "Ft300Model",
    "Ft300Physics",
    "SentFrame",
    "TruthLike",
    "emulated_port",
    "schedule_from",
    "standard_schedule",
    "wrench_from_truth",
]

STANDARD_GRAVITY_M_PER_S2 = 9.80665
#: The stream's nominal period (100 Hz).
FRAME_PERIOD_S = 0.01

#: The model's own fault kinds (the harness applies the byte-level ones).
FAULT_KINDS: Mapping[str, str] = {
    "boots_streaming": "the sensor is already streaming when the host connects (at boot)",
    "partial_jam": "a jam (run of 0xFF) that does not stop the stream",
    "bad_crc": "one stream frame with a corrupted CRC",
    "frame_drop_bytes": "byte(s) lost inside one stream frame (params count, default 1)",
    "header_in_payload": "a frame whose payload holds 0x20 0x4E (params offset 0-10: where "
    "in the 12 payload bytes; default 0, Fx = 200.00 N)",
    "stream_stop": "the stream stops silently (for duration_s; 0: until the next jam)",
    "saturation": "every value pinned at the range limit for duration_s",
    "offset_drift": "the force offset drifts (params rate_n_per_s, default 1) for duration_s "
    "(0: for ever); the drift stays",
    "frozen": "the same frame repeated, CRC valid, for duration_s",
    "no_reply": "one Modbus request left unanswered",
    "modbus_bad_crc": "one Modbus reply with a corrupted CRC",
    "wrong_slave": "one Modbus reply from another slave id",
    "exception_reply": "one Modbus request answered with exception 4 (device failure)",
    "missing_echo": "the function 16 echo is missing while the stream starts",
    "dead": "the sensor falls silent to everything for duration_s (0: for ever)",
}

#: The ``faults: standard`` schedule: the matrix at moderate rates for long runs. Most
#: faults cost a frame; the rare 200 ms stall and silent stream stop make the driver recover.
STANDARD_FAULTS: tuple[Mapping[str, Any], ...] = (
    {"kind": "bad_crc", "rate_hz": 0.2},
    {"kind": "frame_drop_bytes", "rate_hz": 0.1},
    # In a torque word (My = 20 N·m): the parser test without a force spike that a
    # classifier would rightly take for an interaction.
    {"kind": "header_in_payload", "rate_hz": 0.2, "params": {"offset": 10}},
    {"kind": "garbage", "rate_hz": 0.1, "params": {"count": 6}},
    {"kind": "fragment", "rate_hz": 0.05, "duration_s": 1.0},
    {"kind": "stall", "rate_hz": 0.05, "duration_s": 0.05},
    {"kind": "stall", "rate_hz": 0.02, "duration_s": 0.1},
    {"kind": "stall", "rate_hz": 0.005, "duration_s": 0.2},
    {"kind": "stream_stop", "rate_hz": 0.005},
)


class TruthLike(Protocol):
    """What the model reads of a :class:`hapticframe.kinds.PhysicalTruth` (world frame)."""

    @property
    def orientation_wxyz(self) -> Any: ...
    @property
    def linear_acceleration_m_per_s2(self) -> Any: ...
    @property
    def force_n(self) -> Any: ...
    @property
    def torque_nm(self) -> Any: ...
    @property
    def end_effector_mass_kg(self) -> float: ...


@dataclass(frozen=True)
class Ft300Physics:
    """What the emulated sensor measures besides the environment's wrench.

    Parameters
    ----------
    noise_std_n, noise_std_nm : float
        White noise on each force (N) and torque (N·m) component.
    offset_n : (3,) float
        The sensor's constant force offset ε.
    lever_arm_m : (3,) float
        The end effector's centre of mass in the sensor frame: its load adds r × f_load.
    range_n, range_nm : float
        The measuring range; values beyond it saturate there.
    """

    noise_std_n: float = 0.0
    noise_std_nm: float = 0.0
    offset_n: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    range_n: float = 300.0
    range_nm: float = 30.0


def wrench_from_truth(
    truth: TruthLike, physics: Ft300Physics
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The noiseless force and torque the sensor measures (sensor frame = tool frame).

    f = R_wtᵀ f_env + m_e R_wtᵀ (a_w − g_w) + ε and τ = R_wtᵀ τ_env + r × m_e R_wtᵀ (a_w − g_w),
    with g_w = (0, 0, −9.80665). The load term m_e R_wtᵀ (a_w − g_w) equals m_e R_ti a_imu of
    the force observer for any IMU mounting R_ti, so the mounting does not enter here: a
    load at rest reads +m_e g along tool +z.
    """
    r_wt = rotation_matrix_from_wxyz(truth.orientation_wxyz)
    specific = np.asarray(truth.linear_acceleration_m_per_s2, dtype=float) + np.array(
        [0.0, 0.0, STANDARD_GRAVITY_M_PER_S2]
    )
    load = float(truth.end_effector_mass_kg) * (r_wt.T @ specific)
    force = r_wt.T @ np.asarray(truth.force_n, dtype=float) + load + np.asarray(physics.offset_n)
    torque = r_wt.T @ np.asarray(truth.torque_nm, dtype=float) + np.cross(
        np.asarray(physics.lever_arm_m), load
    )
    return force, torque


@dataclass(frozen=True)
class SentFrame:
    """One stream frame as the model sent it.

    ``intact`` is False when the model corrupted it on purpose (bad CRC, lost bytes): a
    driver must never deliver it. ``fault`` names the value fault that shaped an intact
    frame (``"saturation"``, ``"frozen"``, ``"header_in_payload"``) or is empty.
    """

    time_s: float
    force_n: tuple[float, float, float]
    torque_nm: tuple[float, float, float]
    intact: bool
    fault: str = ""


@dataclass
class _Pending:
    due_s: float
    data: bytes


@dataclass
class _State:
    streaming: bool = False
    next_frame_s: float = math.inf
    ff_run: int = 0
    modbus_ready_s: float = -math.inf
    rx: bytearray = field(default_factory=bytearray)
    rx_time_s: float = -math.inf
    out: list[_Pending] = field(default_factory=list)
    muted_until_s: float = -math.inf
    dead_until_s: float = -math.inf
    frozen_until_s: float = -math.inf
    saturated_until_s: float = -math.inf
    drift_until_s: float = -math.inf
    drift_rate_n_per_s: float = 0.0
    drift_n: float = 0.0
    last_frame_s: float | None = None
    last_counts: tuple[int, ...] | None = None


class Ft300Model(DeviceModel):
    """The FT 300's protocol core, driven by a clock.

    Parameters
    ----------
    rng : numpy.random.Generator
        Noise and the random choices of faults.
    faults : FaultSchedule, optional
        The schedule this model draws its own :data:`FAULT_KINDS` from.
    truth : callable, optional
        ``truth(t)`` → the robot's physical truth at device time ``t``; None: at rest.
    physics : Ft300Physics, optional
    slave_id : int
    firmware : (major, minor, patch)
    serial_number : (letters, number)
    production_year : int
    boot_streaming : bool
        Boot already streaming (as a sensor a previous session left streaming).
    jam_threshold : int
        Consecutive 0xFF bytes that stop the stream.
    jam_recovery_s : float
        Silence after a jam before Modbus requests are served.
    reply_latency_s : float
        Delay of every Modbus reply.
    log_frames : int
        How many sent frames :attr:`sent` keeps.
    """

    def __init__(
        self,
        *,
        rng: np.random.Generator,
        faults: FaultSchedule | None = None,
        truth: Callable[[float], TruthLike] | None = None,
        physics: Ft300Physics | None = None,
        slave_id: int = 9,
        firmware: tuple[int, int, int] = (3, 0, 1),
        serial_number: tuple[str, int] = ("ROB", 1234),
        production_year: int = 2019,
        boot_streaming: bool = False,
        jam_threshold: int = 50,
        jam_recovery_s: float = 0.05,
        reply_latency_s: float = 0.003,
        log_frames: int = 100_000,
    ) -> None:
        super().__init__()
        self._rng = rng
        self._faults = faults
        self._truth = truth
        self.physics = physics or Ft300Physics()
        self.slave_id = slave_id
        self._static_registers: dict[int, int] = {}
        for i, value in enumerate(encode_firmware(*firmware)):
            self._static_registers[REGISTER_FIRMWARE + i] = value
        for i, value in enumerate(encode_serial_number(*serial_number)):
            self._static_registers[REGISTER_SERIAL_NUMBER + i] = value
        self._static_registers[REGISTER_PRODUCTION_YEAR] = production_year
        self._boot_streaming = boot_streaming
        self.jam_threshold = jam_threshold
        self.jam_recovery_s = jam_recovery_s
        self.reply_latency_s = reply_latency_s
        #: Every frame sent (newest last), bounded by ``log_frames``.
        self.sent: deque[SentFrame] = deque(maxlen=log_frames)
        #: Counters of what the device saw: jams honoured, requests served, boots.
        self.stats: dict[str, int] = {"jams": 0, "ignored_jams": 0, "requests": 0, "boots": 0}
        self._booted = False
        self._state = _State()

    # -- DeviceModel -------------------------------------------------------------------------

    @property
    def streaming(self) -> bool:
        """Whether the sensor is in stream mode (muted or not)."""
        return self._state.streaming

    def power_cycle(self) -> None:
        """A replug: the sensor boots again (into Modbus unless ``boot_streaming``)."""
        self._state = _State()
        self._booted = False

    def receive(self, data: bytes, now_s: float) -> None:
        self._boot(now_s)
        state = self._state
        if now_s < state.dead_until_s or not data:
            return
        if state.streaming:
            self._listen_for_jam(data, now_s)
            return
        if now_s < state.modbus_ready_s:
            return  # still settling after a jam: the sensor drops what it hears
        state.rx += data
        state.rx_time_s = now_s
        self._serve(now_s)

    def emit(self, now_s: float) -> bytes:
        self._boot(now_s)
        state = self._state
        self._check_dead(now_s)
        if now_s < state.dead_until_s:
            state.out.clear()
            # frames due while dead are never sent
            if state.streaming:
                state.next_frame_s = max(state.next_frame_s, now_s)
            return b""
        if state.rx and now_s - state.rx_time_s > 0.05:
            state.rx.clear()  # a Modbus frame ends with silence: a torn request is dropped
        out = bytearray()
        keep = []
        for pending in state.out:
            if pending.due_s <= now_s:
                out += pending.data
            else:
                keep.append(pending)
        state.out = keep
        if state.streaming:
            if now_s - state.next_frame_s > 1.0:
                # Nobody pumped for a long time: a real link would have overflowed; skip.
                missed = math.floor((now_s - state.next_frame_s) / FRAME_PERIOD_S)
                state.next_frame_s += missed * FRAME_PERIOD_S
            while state.next_frame_s <= now_s and state.streaming:
                t = state.next_frame_s
                state.next_frame_s = t + FRAME_PERIOD_S
                out += self._stream_frame(t)
        return bytes(out)

    # -- Modbus side -------------------------------------------------------------------------

    def _boot(self, now_s: float) -> None:
        if self._booted:
            return
        self._booted = True
        self.stats["boots"] += 1
        if self._boot_streaming or self._fires("boots_streaming", now_s) is not None:
            self._start_stream(now_s)

    def _fires(self, kind: str, now_s: float) -> FaultEvent | None:
        return None if self._faults is None else self._faults.fires(kind, now_s)

    def _check_dead(self, now_s: float) -> None:
        event = self._fires("dead", now_s)
        if event is not None:
            self._state.dead_until_s = (
                math.inf if event.duration_s <= 0 else now_s + event.duration_s
            )

    def _listen_for_jam(self, data: bytes, now_s: float) -> None:
        state = self._state
        for byte in data:
            state.ff_run = state.ff_run + 1 if byte == 0xFF else 0
            if state.ff_run < self.jam_threshold:
                continue
            state.ff_run = 0
            if self._fires("partial_jam", now_s) is not None:
                self.stats["ignored_jams"] += 1
                continue
            self.stats["jams"] += 1
            state.streaming = False
            state.next_frame_s = math.inf
            state.muted_until_s = -math.inf
            state.modbus_ready_s = now_s + self.jam_recovery_s
            state.rx.clear()
            return

    def _serve(self, now_s: float) -> None:
        rx = self._state.rx
        while rx:
            if rx[0] != self.slave_id:
                del rx[0]  # another slave's request or line noise (the jam's tail)
                continue
            try:
                request = parse_request(bytes(rx))
            except ProtocolError:
                del rx[0]
                continue
            if request is None:
                return  # wait for the rest
            _, function, first, values = request
            del rx[: 8 if function == FUNCTION_READ_HOLDING else 9 + 2 * len(values)]
            self.stats["requests"] += 1
            self._answer(function, first, values, now_s)

    def _registers(self, first: int, count: int, now_s: float) -> list[int] | None:
        live: dict[int, int] = {}
        if first < REGISTER_FORCE_TORQUE + 6 and first + count > REGISTER_FORCE_TORQUE:
            force, torque = self._measure(now_s)
            for i, c in enumerate(quantise(force, torque)):
                live[REGISTER_FORCE_TORQUE + i] = c & 0xFFFF
        values = []
        for register in range(first, first + count):
            value = live.get(register, self._static_registers.get(register))
            if value is None:
                return None
            values.append(value)
        return values

    def _answer(self, function: int, first: int, values: tuple[int, ...], now_s: float) -> None:
        if self._fires("no_reply", now_s) is not None:
            return
        start_stream = False
        reply: bytes
        if self._fires("exception_reply", now_s) is not None:
            reply = encode_exception_reply(function, 4, slave=self.slave_id)
        elif function == FUNCTION_READ_HOLDING:
            count = values[0]
            registers = self._registers(first, count, now_s) if 1 <= count <= 125 else None
            if registers is None:
                reply = encode_exception_reply(function, 2 if count <= 125 else 3,
                                               slave=self.slave_id)
            else:
                reply = encode_read_reply(registers, slave=self.slave_id)
        elif function == FUNCTION_WRITE_MULTIPLE and first == REGISTER_OUTPUT_MODE and len(
            values
        ) == 1:
            reply = encode_write_reply(first, 1, slave=self.slave_id)
            start_stream = values[0] == STREAM_MODE_VALUE
        else:
            reply = encode_exception_reply(function, 2, slave=self.slave_id)
        if self._fires("wrong_slave", now_s) is not None:
            reply = append_crc16(bytes(((self.slave_id % 247) + 1,)) + reply[1:-2])
        if self._fires("modbus_bad_crc", now_s) is not None:
            reply = reply[:-1] + bytes((reply[-1] ^ 0xA5,))
        due = now_s + self.reply_latency_s
        if start_stream:
            if self._fires("missing_echo", now_s) is not None:
                reply = b""
            self._start_stream(due)
        if reply:
            self._state.out.append(_Pending(due, reply))

    def _start_stream(self, now_s: float) -> None:
        state = self._state
        state.streaming = True
        state.ff_run = 0
        state.rx.clear()
        state.next_frame_s = now_s + FRAME_PERIOD_S

    # -- stream side -------------------------------------------------------------------------

    def _measure(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        physics = self.physics
        if self._truth is None:
            force = np.asarray(physics.offset_n, dtype=float).copy()
            torque = np.zeros(3)
        else:
            force, torque = wrench_from_truth(self._truth(t), physics)
        force[0] += self._state.drift_n
        force = force + physics.noise_std_n * self._rng.standard_normal(3)
        torque = torque + physics.noise_std_nm * self._rng.standard_normal(3)
        force = np.clip(force, -physics.range_n, physics.range_n)
        torque = np.clip(torque, -physics.range_nm, physics.range_nm)
        return force, torque

    def _advance_drift(self, t: float) -> None:
        """Accumulate the offset drift (along x) up to frame time ``t``."""
        state = self._state
        if state.last_frame_s is not None and state.last_frame_s < state.drift_until_s:
            span = min(t, state.drift_until_s) - state.last_frame_s
            state.drift_n += state.drift_rate_n_per_s * max(span, 0.0)
        event = self._fires("offset_drift", t)
        if event is not None:
            state.drift_rate_n_per_s = float(event.params.get("rate_n_per_s", 1.0))
            state.drift_until_s = math.inf if event.duration_s <= 0 else t + event.duration_s

    def _stream_frame(self, t: float) -> bytes:
        state = self._state
        for kind, attribute in (
            ("stream_stop", "muted_until_s"),
            ("frozen", "frozen_until_s"),
            ("saturation", "saturated_until_s"),
        ):
            event = self._fires(kind, t)
            if event is not None:
                until = math.inf if event.duration_s <= 0 else t + event.duration_s
                setattr(state, attribute, until)
        self._advance_drift(t)
        state.last_frame_s = t
        if t < state.muted_until_s:
            return b""
        fault = ""
        if t < state.frozen_until_s and state.last_counts is not None:
            counts = state.last_counts
            fault = "frozen"
        else:
            force, torque = self._measure(t)
            if t < state.saturated_until_s:
                force = np.where(force < 0, -self.physics.range_n, self.physics.range_n)
                torque = np.where(torque < 0, -self.physics.range_nm, self.physics.range_nm)
                fault = "saturation"
            counts = quantise(force, torque)
        event = self._fires("header_in_payload", t)
        if event is not None:
            offset = int(event.params.get("offset", 0))
            if not 0 <= offset <= 10:
                raise ValueError(f"header_in_payload offset must be in 0..10, got {offset}")
            payload = bytearray(encode_stream_frame(counts)[2:14])
            payload[offset : offset + 2] = STREAM_HEADER
            counts = tuple(int(c) for c in np.frombuffer(bytes(payload), dtype="<i2"))
            fault = fault or "header_in_payload"
        state.last_counts = counts
        frame = encode_stream_frame(counts)
        intact = True
        if self._fires("bad_crc", t) is not None:
            frame = frame[:-2] + bytes((frame[-2] ^ 0x5A, frame[-1]))
            intact = False
        event = self._fires("frame_drop_bytes", t)
        if event is not None:
            count = max(1, min(int(event.params.get("count", 1)), STREAM_FRAME_LENGTH - 3))
            keep = list(range(STREAM_FRAME_LENGTH))
            for index in sorted(
                self._rng.choice(np.arange(2, STREAM_FRAME_LENGTH), size=count, replace=False),
                reverse=True,
            ):
                del keep[int(index)]
            frame = bytes(frame[i] for i in keep)
            intact = False
        force_n, torque_nm = decode_stream_values(counts)
        self.sent.append(SentFrame(t, force_n, torque_nm, intact, fault))
        return frame


def standard_schedule(rng: np.random.Generator) -> FaultSchedule:
    """The ``faults: standard`` schedule (:data:`STANDARD_FAULTS`) drawn with ``rng``."""
    return FaultSchedule.from_config(STANDARD_FAULTS, rng)


def schedule_from(
    faults: str | Sequence[Mapping[str, Any]], rng: np.random.Generator
) -> FaultSchedule | None:
    """A fault schedule from a config value: ``"none"``, ``"standard"`` or entries."""
    if faults == "none":
        return None
    if faults == "standard":
        return standard_schedule(rng)
    if isinstance(faults, str):
        raise ValueError(f"faults must be 'none', 'standard' or a list, got {faults!r}")
    return FaultSchedule.from_config(list(faults), rng)


def emulated_port(
    config: Any,
    rng: np.random.Generator,
    *,
    truth: Callable[[float], TruthLike] | None,
    follow: Callable[[], float] | None,
    start_s: float,
) -> EmulatedPort:
    """The ``port: emulated`` link: an :class:`Ft300Model` built from the sensor's config
    (an ``Ft300Config``) behind a pseudo-terminal, on a fake clock that starts at
    ``start_s`` and that each read moves to ``follow()`` (the robot's simulation time), or
    one frame period on without it. ``rng`` seeds the noise and the faults."""
    noise_rng, fault_rng = rng.spawn(2)
    schedule = schedule_from(config.faults, fault_rng)
    physics = Ft300Physics(
        noise_std_n=config.noise_std_n,
        noise_std_nm=config.noise_std_nm,
        offset_n=config.offset_n,
        lever_arm_m=config.lever_arm_m,
        range_n=config.range_n,
        range_nm=config.range_nm,
    )
    model = Ft300Model(
        rng=noise_rng,
        faults=schedule,
        truth=truth,
        physics=physics,
        slave_id=config.slave_id,
        firmware=config.emulator_firmware,
    )
    return EmulatedPort(model, FakeClock(start_s), faults=schedule, follow=follow,
                        link_name="ft300")
