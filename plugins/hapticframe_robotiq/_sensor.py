"""The Robotiq FT 300 driver: a sensor with a device lifecycle, watchdogs and bounded recovery.

``configure`` opens the port, silences a stream left running (the jam) and identifies the
sensor over Modbus; ``activate`` starts the 100 Hz stream and zeroes it; ``read`` drains the
port without blocking, parses frames (resynchronising by one byte) and stamps each sample
with host time. Watchdogs are expressed in time: no byte for ``byte_timeout_s`` counts a
stall, no valid frame for ``frame_timeout_s`` recovers (reconnect with backoff when the link
dropped, re-jam, restart the stream), at most ``max_recoveries`` times in a row before
:class:`~hapticframe.devices.DeviceError`. Every wait is bounded by the clock.

With ``port: emulated`` the same code talks to :class:`Ft300Model` behind a pseudo-terminal,
paced by a :class:`~hapticframe.devices.FakeClock` that each ``read`` advances to the
simulation time of the robot input (one frame period per read without a robot).
"""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any, TypeVar

import numpy as np

from hapticframe.devices import (
    Backoff,
    ByteTransport,
    Clock,
    ClockSync,
    DeviceError,
    DeviceLifecycle,
    FakeClock,
    FixedFrameParser,
    LifecycleState,
    MonotonicClock,
    PtyEmulator,
    SerialTransport,
    TransportError,
)
from hapticframe.kinds import (
    BuildContext,
    ChannelInfo,
    PhysicalTruthSource,
    RunOutcome,
    SampleBatch,
    Sensor,
)

from ._config import Ft300Config
from ._emulator import FRAME_PERIOD_S, Ft300Model, Ft300Physics, schedule_from
from ._protocol import (
    FORCE_COUNTS_PER_N,
    JAM_BYTES,
    REGISTER_FIRMWARE,
    REGISTER_OUTPUT_MODE,
    REGISTER_SERIAL_NUMBER,
    STREAM_FRAME_LENGTH,
    STREAM_HEADER,
    STREAM_MODE_VALUE,
    TORQUE_COUNTS_PER_NM,
    WRITE_REPLY_LENGTH,
    DeviceInfo,
    ModbusException,
    ProtocolError,
    decode_firmware,
    decode_serial_number,
    decode_stream_frame,
    parse_read_reply,
    parse_write_reply,
    read_reply_length,
    read_request,
    reply_length,
    write_request,
)

__all__ = ["FORCE_CHANNEL", "TORQUE_CHANNEL", "Ft300Sensor"]

FORCE_CHANNEL = "force_n"
TORQUE_CHANNEL = "torque_nm"
#: How often the driver looks at the port while it waits (the official driver: 4 ms).
POLL_S = 0.004
#: Settling after a jam before Modbus (the official driver waits 100 ms).
_JAM_SETTLE_S = 0.1
#: A jam is given this long (at least) to silence the stream before the next burst.
_JAM_LISTEN_S = 0.5
#: Emulated mode: the device clock starts this long (plus tare_s) before the simulation so
#: that the handshake and the tare are over when the simulation begins.
_EMULATED_LEAD_S = 0.5

T = TypeVar("T")


def _truth_source(context: BuildContext) -> PhysicalTruthSource | None:
    """The robot input that provides physical truth (a ``PhysicalTruthSource``), or None."""
    inputs = list(context.inputs.items())
    if not inputs:
        return None
    if len(inputs) > 1:
        names = ", ".join(repr(k) for k, _ in inputs)
        raise ValueError(
            f"sensor {context.id!r} (type 'robotiq-ft300') takes at most one input, the robot "
            f"it is mounted on; got {names}"
        )
    name, robot = inputs[0]
    if not isinstance(robot, PhysicalTruthSource):
        raise ValueError(
            f"sensor {context.id!r} (type 'robotiq-ft300'): input {name!r} "
            f"({type(robot).__name__}) does not expose its physical truth "
            "(hapticframe.kinds.PhysicalTruthSource: physical_truth(t) and truth_time_s), so "
            "the emulated sensor cannot measure it; drop the input or use a simulated robot "
            "that provides it"
        )
    return robot


class Ft300Sensor(Sensor, DeviceLifecycle):
    """A Robotiq FT 300 force/torque sensor: ``force_n (3,)`` N and ``torque_nm (3,)`` N·m.

    Parameters
    ----------
    config : Ft300Config
    context : BuildContext
        ``inputs`` may hold the robot the sensor is mounted on (emulated mode reads its
        physical truth; a real port ignores it).
    transport : ByteTransport, optional
        Use this link instead of opening ``config.port`` (a lab's own adapter, or an
        :class:`~hapticframe.devices.EmulatedTransport` in fast tests).
    clock : Clock, optional
        The driver's clock (default: a monotonic clock, or a fake clock in emulated mode).
        When it is a :class:`~hapticframe.devices.FakeClock`, each read advances it.

    Attributes
    ----------
    device_info : DeviceInfo or None
        Firmware, serial number and production year, once configured.
    model : Ft300Model or None
        The emulated device (``port: emulated``).
    emulator : PtyEmulator or None
    modbus_errors : dict of str to int
        Failed Modbus attempts by cause (``crc``, ``wrong_reply``, ``exception``, ``timeout``).
    """

    def __init__(
        self,
        config: Ft300Config,
        context: BuildContext,
        *,
        transport: ByteTransport | None = None,
        clock: Clock | None = None,
    ) -> None:
        super().__init__(config, context)
        self.config: Ft300Config = config
        self.max_recoveries = config.max_recoveries
        self.live = not config.emulated and not isinstance(clock, FakeClock)
        self._robot = _truth_source(context) if config.emulated else None
        self._given_transport = transport
        self._transport: ByteTransport | None = transport
        if clock is None:
            clock = self._emulated_clock() if config.emulated else MonotonicClock()
        self.clock: Clock = clock
        self._origin_s = self.clock.now() if self._robot is None else float(
            self._robot.truth_time_s
        )
        rate = 1.0 / FRAME_PERIOD_S
        self._channels = MappingProxyType({
            FORCE_CHANNEL: ChannelInfo(shape=(3,), unit="N", rate_hz=rate),
            TORQUE_CHANNEL: ChannelInfo(shape=(3,), unit="N·m", rate_hz=rate),
        })
        self._parser = FixedFrameParser(STREAM_HEADER, STREAM_FRAME_LENGTH)
        self.device_info: DeviceInfo | None = None
        self.model: Ft300Model | None = None
        self.emulator: PtyEmulator | None = None
        self._link_dir: Path | None = None
        self.modbus_errors = {"crc": 0, "wrong_reply": 0, "exception": 0, "timeout": 0}
        self._offset = np.zeros(6)
        self._tare_until: float | None = None
        self._tare_sum = np.zeros(6)
        self._tare_n = 0
        self._streaming = False
        self._last_byte_s = -math.inf
        self._last_frame_s = -math.inf
        self._stalled = False
        self._last_counts: tuple[int, ...] | None = None
        self._same_run = 0
        self._last_t = -math.inf
        # The stream's own clock: a frame every 10 ms, counted from the stream's start and
        # mapped onto host time (receipt times only say when a read found the frames). No
        # drift fit: over its one-second window a crystal's drift is a few microseconds,
        # while a slope fitted to jittery receipts would swing the mapping by milliseconds.
        self._stream_clock = ClockSync(FRAME_PERIOD_S, window=100, max_drift=0.0)
        self._stream_seq: int | None = None
        self._rejected_frames = 0  # frames that failed their CRC since the last valid one
        self._rows: list[tuple[float, tuple[int, ...], bool, bool]] = []
        saturation = (round(config.range_n * FORCE_COUNTS_PER_N),
                      round(config.range_nm * TORQUE_COUNTS_PER_NM))
        self._saturation_counts = saturation

    def _emulated_clock(self) -> FakeClock:
        robot = _truth_source(self.context)
        start = 0.0 if robot is None else float(robot.truth_time_s)
        return FakeClock(start - _EMULATED_LEAD_S - self.config.tare_s)

    # -- Sensor ------------------------------------------------------------------------------

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """The tare subtracted from every sample: force (N) and torque (N·m)."""
        return (self._offset[:3] / FORCE_COUNTS_PER_N).copy(), (
            self._offset[3:] / TORQUE_COUNTS_PER_NM
        ).copy()

    def read(self) -> SampleBatch:
        """The samples received since the previous read (never blocks on a real port).

        Raises
        ------
        DeviceError
            When the sensor stopped and bounded recovery could not bring it back.
        """
        self._ensure_active()
        clock = self.clock
        if isinstance(clock, FakeClock):
            if self._robot is not None:
                target = float(self._robot.truth_time_s)
            else:
                target = clock.now() + FRAME_PERIOD_S
            self._poll()
            # Sub-steps as a live driver polls: watchdogs and receipt times in device time.
            for _ in range(100_000):
                if clock.now() >= target:
                    break
                clock.advance_to(min(target, clock.now() + POLL_S))
                self._poll()
        else:
            self._poll()
        return self._take_batch()

    def _ensure_active(self) -> None:
        state = self.lifecycle_state
        if state is not LifecycleState.ACTIVE:
            raise DeviceError(
                f"device {self.id!r} (robotiq-ft300 on {self.config.port}) is {state.value}, "
                "not active; configure() and activate() it first",
                device_id=self.id,
            )

    def tare(self, *, wait: bool = False) -> None:
        """Zero the sensor on the mean of the valid samples of the next ``tare_s``.

        Without ``wait`` it returns at once (the samples meanwhile keep the old zero);
        with ``wait`` it polls the sensor until the tare is done (bounded).
        """
        self._tare_until = self.clock.now() + self.config.tare_s
        self._tare_sum[:] = 0.0
        self._tare_n = 0
        if wait:
            self._wait_for_tare()

    @property
    def tare_pending(self) -> bool:
        """Whether a requested tare is still collecting samples."""
        return self._tare_until is not None

    def reset(self) -> None:
        """Drop samples received and not yet read."""
        self._rows.clear()

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        return {}

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    # -- lifecycle hooks ---------------------------------------------------------------------

    def on_configure(self) -> None:
        if self.config.emulated and self.emulator is None:
            self._start_emulator()
        self._open()
        self._jam()
        self.device_info = self._identify()

    def on_activate(self) -> None:
        if self._transport is None or not self._transport.is_open:
            self._open()
        self._start_stream()
        if self.config.tare_s > 0:
            self.tare(wait=True)
        self._rows.clear()  # what came during the handshake and the tare is not data

    def on_deactivate(self) -> None:
        transport = self._transport
        self._streaming = False
        if transport is not None and transport.is_open:
            transport.write(JAM_BYTES)
            # Let the bytes reach the device (and a clock-paced emulator hear them).
            self.clock.sleep(POLL_S)

    def on_cleanup(self) -> None:
        self._release()

    def on_recover(self, error: Exception) -> None:
        transport = self._transport
        if isinstance(error, TransportError) or transport is None or not transport.is_open:
            self._reconnect()
        self._jam()
        self._start_stream()

    def _release(self) -> None:
        if self._transport is not None and self._transport is not self._given_transport:
            self._transport.close()
            self._transport = None
        elif self._given_transport is not None:
            self._given_transport.close()
        if self.emulator is not None:
            self.emulator.stop()
            self.emulator = None
        if self._link_dir is not None:
            shutil.rmtree(self._link_dir, ignore_errors=True)
            self._link_dir = None

    # -- link --------------------------------------------------------------------------------

    def _start_emulator(self) -> None:
        config = self.config
        if not isinstance(self.clock, FakeClock):
            raise DeviceError(f"device {self.id!r}: the emulated port needs a fake clock",
                              device_id=self.id)
        noise_rng, fault_rng = self.context.rng.spawn(2)
        schedule = schedule_from(config.faults, fault_rng)
        robot = self._robot
        physics = Ft300Physics(
            noise_std_n=config.noise_std_n,
            noise_std_nm=config.noise_std_nm,
            offset_n=config.offset_n,
            lever_arm_m=config.lever_arm_m,
            range_n=config.range_n,
            range_nm=config.range_nm,
        )
        self.model = Ft300Model(
            rng=noise_rng,
            faults=schedule,
            truth=None if robot is None else robot.physical_truth,
            physics=physics,
            slave_id=config.slave_id,
            firmware=config.emulator_firmware,
        )
        self._link_dir = Path(tempfile.mkdtemp(prefix="hapticframe-ft300-"))
        self.emulator = PtyEmulator(
            self.model, clock=self.clock, faults=schedule, link_path=self._link_dir / "ft300"
        ).start()

    def _open(self) -> None:
        if self._transport is None:
            port = self.emulator.path if self.emulator is not None else self.config.port
            self._transport = SerialTransport(port, baudrate=self.config.baudrate)
        self._transport.open()
        self._parser.reset()

    def _link(self) -> ByteTransport:
        if self._transport is None:
            raise TransportError(f"{self.config.port} is not open")
        return self._transport

    def _reconnect(self) -> None:
        """Close and reopen the port, waiting a growing delay before each attempt."""
        if self._transport is not None:
            self._transport.close()
        last: Exception | None = None
        for delay in Backoff(attempts=self.config.reconnect_attempts):
            self.clock.sleep(delay)
            try:
                self._open()
            except TransportError as exc:
                last = exc
                continue
            self.health.reconnects += 1
            return
        raise TransportError(
            f"{self.config.port} did not reopen after {self.config.reconnect_attempts} "
            f"attempts: {last}"
        )

    def _read_link(self) -> bytes:
        data = self._link().read_available()
        if data:
            self._last_byte_s = self.clock.now()
            self._stalled = False
        return data

    # -- handshake ---------------------------------------------------------------------------

    def _jam(self) -> None:
        """Silence a running stream: 0xFF bursts until no byte comes for ``byte_timeout_s``."""
        link = self._link()
        self._streaming = False
        for _ in range(self.config.jam_attempts):
            link.write(JAM_BYTES)
            if self._await_silence():
                self.clock.sleep(_JAM_SETTLE_S)
                link.reset_input()
                self._parser.reset()
                return
        raise ProtocolError(
            f"the stream on {self.config.port} did not stop after {self.config.jam_attempts} "
            "jams (0xFF bursts)"
        )

    def _await_silence(self) -> bool:
        clock = self.clock
        quiet_s = self.config.byte_timeout_s
        start = last = clock.now()
        listen = max(_JAM_LISTEN_S, 4 * quiet_s)
        for _ in range(math.ceil(listen / POLL_S) + 2):
            clock.sleep(POLL_S)
            data = self._link().read_available()
            now = clock.now()
            if data:
                self.health.bytes += len(data)
                last = now
            elif now - last >= quiet_s:
                return True
            if now - start >= listen:
                return False
        return False

    def _await_reply(self, expected: int) -> bytes | None:
        clock = self.clock
        link = self._link()
        buffer = bytearray()
        deadline = clock.now() + self.config.modbus_timeout_s
        for _ in range(math.ceil(self.config.modbus_timeout_s / POLL_S) + 2):
            clock.sleep(POLL_S)
            buffer += link.read_available()
            length = reply_length(buffer, expected)
            if length is not None and len(buffer) >= length:
                self.health.bytes += length
                return bytes(buffer[:length])
            if clock.now() >= deadline:
                break
        return None

    def _transact(self, request: bytes, expected: int, parse: Callable[[bytes], T]) -> T:
        """One Modbus request, retried on a missing or broken reply."""
        link = self._link()
        last: Exception | None = None
        for _ in range(self.config.modbus_retries):
            link.reset_input()
            link.write(request)
            reply = self._await_reply(expected)
            if reply is None:
                self.health.timeouts += 1
                self.modbus_errors["timeout"] += 1
                last = TimeoutError(f"no reply in {self.config.modbus_timeout_s} s")
                continue
            try:
                return parse(reply)
            except ModbusException as exc:
                self.health.timeouts += 1  # answered, but with no usable reply
                self.modbus_errors["exception"] += 1
                last = exc
            except ProtocolError as exc:
                if "CRC" in str(exc):
                    self.health.crc_errors += 1
                    self.modbus_errors["crc"] += 1
                else:
                    self.health.timeouts += 1
                    self.modbus_errors["wrong_reply"] += 1
                last = exc
        raise ProtocolError(
            f"request {request.hex(' ')} to {self.config.port} failed "
            f"{self.config.modbus_retries} times: {last}"
        )

    def _identify(self) -> DeviceInfo:
        slave = self.config.slave_id
        firmware = self._transact(
            read_request(REGISTER_FIRMWARE, 3, slave=slave),
            read_reply_length(3),
            lambda reply: decode_firmware(parse_read_reply(reply, 3, slave=slave)),
        )
        registers = self._transact(
            read_request(REGISTER_SERIAL_NUMBER, 5, slave=slave),
            read_reply_length(5),
            lambda reply: parse_read_reply(reply, 5, slave=slave),
        )
        return DeviceInfo(firmware, decode_serial_number(registers[:4]), registers[4])

    def _start_stream(self) -> None:
        """Write 0x0200 to register 410; accept the echo, or stream frames when it is lost."""
        self._stream_clock.reset()  # a new stream: its frames count from zero again
        self._stream_seq = None
        self._rejected_frames = 0
        slave = self.config.slave_id
        request = write_request(REGISTER_OUTPUT_MODE, [STREAM_MODE_VALUE], slave=slave)
        link = self._link()
        clock = self.clock
        last: Exception | None = None
        for _ in range(self.config.modbus_retries):
            link.reset_input()
            self._parser.reset()
            link.write(request)
            buffer = bytearray()
            echo: bool | None = None
            deadline = clock.now() + self.config.modbus_timeout_s
            for _ in range(math.ceil(self.config.modbus_timeout_s / POLL_S) + 2):
                clock.sleep(POLL_S)
                data = link.read_available()
                now = clock.now()
                if echo is None:
                    buffer += data
                    length = reply_length(buffer, WRITE_REPLY_LENGTH)
                    if length is not None and len(buffer) >= length:
                        try:
                            parse_write_reply(bytes(buffer[:length]), REGISTER_OUTPUT_MODE, 1,
                                              slave=slave)
                        except ModbusException as exc:
                            self.modbus_errors["exception"] += 1
                            self.health.timeouts += 1
                            last = exc
                            break
                        except ProtocolError:
                            echo = False  # maybe the stream started and the echo was lost
                            data = bytes(buffer)
                        else:
                            echo = True
                            self.health.bytes += length
                            data = bytes(buffer[length:])
                if echo is not None:
                    frames = self._parser.feed(data)
                    if echo or frames:
                        if not echo:
                            self.health.timeouts += 1
                            self.modbus_errors["timeout"] += 1
                        self._streaming = True
                        self._last_byte_s = self._last_frame_s = now
                        self._stalled = False
                        if frames:
                            self._accept(frames, now)
                        return
                if clock.now() >= deadline:
                    self.health.timeouts += 1
                    self.modbus_errors["timeout"] += 1
                    last = TimeoutError("no echo and no stream")
                    break
        raise ProtocolError(
            f"the stream on {self.config.port} did not start after "
            f"{self.config.modbus_retries} attempts: {last}"
        )

    # -- stream ------------------------------------------------------------------------------

    def _poll(self) -> None:
        """One look at the port: parse, deliver, run the watchdogs (recover when they fire)."""
        now = self.clock.now()
        silent_since = self._last_byte_s
        try:
            data = self._read_link()
        except TransportError as exc:
            self.recover(exc)
            return
        rejected_before = self._parser.stats.crc_errors
        frames = self._parser.feed(data)
        self._rejected_frames += self._parser.stats.crc_errors - rejected_before
        self.health.add_parser(self._parser.stats)
        if frames:
            self._accept(frames, now, silent_s=now - silent_since)
            return
        if now - self._last_byte_s > self.config.byte_timeout_s and not self._stalled:
            self._stalled = True
            self.health.stalls += 1
        if now - self._last_frame_s > self.config.frame_timeout_s:
            self.health.timeouts += 1
            self.recover(
                TimeoutError(
                    f"no valid frame from {self.config.port} for "
                    f"{now - self._last_frame_s:.3f} s"
                )
            )

    def _accept(self, frames: list[bytes], now: float, silent_s: float = 0.0) -> None:
        self._last_frame_s = now
        n = len(frames)
        if not n:
            return
        times = self._sample_times(n, now, silent_s)
        for k, frame in enumerate(frames):
            counts = decode_stream_frame(frame)
            t = max(times[k], self._last_t + 1e-6)
            self._last_t = t
            if counts == self._last_counts:
                self._same_run += 1
            else:
                self._same_run, self._last_counts = 1, counts
            frozen = (
                self.config.frozen_frames is not None
                and self._same_run > self.config.frozen_frames
            )
            force_sat, torque_sat = self._saturation_counts
            force_ok = not frozen and max(abs(c) for c in counts[:3]) < force_sat
            torque_ok = not frozen and max(abs(c) for c in counts[3:]) < torque_sat
            if not (force_ok and torque_ok):
                self.health.invalid_samples += 1
            if self._tare_until is not None:
                if t < self._tare_until:
                    if force_ok and torque_ok:
                        self._tare_sum += counts
                        self._tare_n += 1
                else:
                    self._finish_tare()
            if t >= self._origin_s:
                self._rows.append((t, counts, force_ok, torque_ok))

    def _sample_times(self, n: int, now: float, silent_s: float) -> list[float]:
        """Host times of ``n`` frames that one read found at ``now``.

        Frames that arrive together were sent one period apart, so each is first dated back
        from ``now``. Those receipt times still jitter with the reads (a frame found 8 ms
        late behind a slow write, the next on time), and a force rate over them would swing
        with the jitter: instead each frame is numbered on the stream's own 100 Hz clock and
        :class:`~hapticframe.devices.ClockSync` maps the numbers onto host time through the
        promptest receipts. Frames lost before these are counted from the evidence: the
        frames that failed their CRC, or, for frames that never came (a stall that dropped
        them), a silent link and a receipt whole periods past the next frame's slot. A late
        frame on a busy link (a slow adapter delivering a backlog) is late, not a sign of
        lost ones. Where the evidence is unclear the count errs low: a frame counted lost
        that was not would date the next one a period early, onto its predecessor, while
        one missed shifts the dates by a period for a window's length, evenly spaced.
        """
        sync = self._stream_clock
        rejected, self._rejected_frames = self._rejected_frames, 0
        numbers = []
        for k in range(n):
            receipt = now - (n - 1 - k) * FRAME_PERIOD_S
            if self._stream_seq is None:  # a new stream: the outage before it cost frames
                number = 0
                if math.isfinite(self._last_t):
                    outage = receipt - self._last_t
                    self.health.dropped_samples += max(0, round(outage / FRAME_PERIOD_S) - 1)
            else:  # frames the device sent and we never got are dropped samples
                late = receipt - sync.host_time((self._stream_seq + 1) * FRAME_PERIOD_S)
                silent = k == 0 and silent_s >= 1.5 * FRAME_PERIOD_S
                lost_in_time = max(0, math.floor(late / FRAME_PERIOD_S)) if silent else 0
                lost = max(lost_in_time, rejected if k == 0 else 0)
                number = self._stream_seq + 1 + lost
                self.health.dropped_samples += lost
            self._stream_seq = number
            sync.update(number * FRAME_PERIOD_S, receipt)
            numbers.append(number)
        return [sync.host_time(number * FRAME_PERIOD_S) for number in numbers]

    def _finish_tare(self) -> None:
        needed = max(1, math.floor(0.5 * self.config.tare_s / FRAME_PERIOD_S))
        if self._tare_n >= needed:
            self._offset = self._tare_sum / self._tare_n
        self._tare_until = None

    def _wait_for_tare(self) -> None:
        clock = self.clock
        budget = self.config.tare_s + 2.0 + self.max_recoveries * 5.0
        start = clock.now()
        for _ in range(math.ceil(budget / POLL_S) + 2):
            if self._tare_until is None:
                break
            clock.sleep(POLL_S)
            self._poll()
            if self._tare_until is not None and clock.now() >= self._tare_until + \
                    self.config.frame_timeout_s:
                self._finish_tare()
            if clock.now() - start > budget:
                break
        if self._tare_until is not None or self._tare_n < max(
            1, math.floor(0.5 * self.config.tare_s / FRAME_PERIOD_S)
        ):
            self._tare_until = None
            raise ProtocolError(
                f"tare on {self.config.port} got {self._tare_n} valid frames in "
                f"{self.config.tare_s} s"
            )

    def _take_batch(self) -> SampleBatch:
        rows, self._rows = self._rows, []
        if not rows:
            return SampleBatch.empty(self._channels)
        times = np.array([r[0] for r in rows])
        counts = np.array([r[1] for r in rows], dtype=float) - self._offset
        force = counts[:, :3] / FORCE_COUNTS_PER_N
        torque = counts[:, 3:] / TORQUE_COUNTS_PER_NM
        force_ok = np.array([r[2] for r in rows])
        torque_ok = np.array([r[3] for r in rows])
        return SampleBatch(
            times,
            {FORCE_CHANNEL: force, TORQUE_CHANNEL: torque},
            {FORCE_CHANNEL: force_ok, TORQUE_CHANNEL: torque_ok},
        )
