"""The Robotiq FT 300 driver: a sensor with a device lifecycle, watchdogs and bounded recovery.

``configure`` opens the port, silences a stream left running (the jam) and identifies the
sensor over Modbus; ``activate`` starts the 100 Hz stream and zeroes it; ``read`` drains the
port without blocking, parses frames (resynchronising by one byte) and stamps each sample
with host time. Watchdogs are expressed in time: no byte for ``byte_timeout_s`` counts a
stall, no valid frame for ``frame_timeout_s`` recovers (reconnect with backoff when the link
dropped, re-jam, restart the stream), at most ``max_recoveries`` times in a row before
:class:`~hapticframe.devices.DeviceError`. Every wait is bounded by the clock.

A read never waits: recovery runs in steps, one per look at the port (a reconnect's backoff,
the jam's silence and the restart are deadlines on the clock, not sleeps), and a read of a
recovering sensor returns what it has — nothing — at once, so the run loop's safety checks go
on while the sensor is away.

The driver talks to a :class:`~hapticframe.devices.DevicePort`: a serial device, or with
``port: emulated`` an :class:`Ft300Model` behind a pseudo-terminal whose fake clock each read
moves to the robot's simulation time. The code path is the same for both.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator, Mapping
from types import MappingProxyType
from typing import Any, TypeVar

import numpy as np

from hapticframe.devices import (
    Backoff,
    ByteTransport,
    Clock,
    DeviceError,
    DeviceLifecycle,
    DevicePort,
    EmulatedPort,
    FixedFrameParser,
    LifecycleState,
    PtyEmulator,
    TransportError,
    port_for,
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
from ._emulator import FRAME_PERIOD_S, Ft300Model, emulated_port
from ._numbering import StreamNumbering
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
#: Bound on the steps of one wait (each wait also ends on its deadline in time).
_MAX_STEPS = 100_000
#: Emulated mode: the device clock starts this long (plus tare_s) before the simulation so
#: that the handshake and the tare are over when the simulation begins.
_EMULATED_LEAD_S = 0.5

T = TypeVar("T")
#: A step of the handshake: yields where it waits for the device, returns its result.
Steps = Generator[None, None, T]


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
    port : DevicePort, optional
        Where the link and the clock come from (default: ``config.port``, a serial device,
        or the emulator for ``emulated``).
    transport : ByteTransport, optional
        Use this link instead of opening ``config.port`` (a lab's own adapter, or an
        :class:`~hapticframe.devices.EmulatedTransport` in fast tests); with ``clock``,
        made into a port by :func:`~hapticframe.devices.port_for`.
    clock : Clock, optional
        The driver's clock for ``transport``; :func:`~hapticframe.devices.port_for` decides
        whether each read moves it (a fake clock, one frame period at a time).

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
        port: DevicePort | None = None,
        transport: ByteTransport | None = None,
        clock: Clock | None = None,
    ) -> None:
        super().__init__(config, context)
        self.config: Ft300Config = config
        self.max_recoveries = config.max_recoveries
        self._robot = _truth_source(context) if config.emulated else None
        if port is None:
            port = self._default_port(transport, clock)
        self.port: DevicePort = port
        self.live = port.live
        self.clock: Clock = port.clock
        self._transport: ByteTransport | None = None
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
        # The stream's own clock: a frame every 10 ms, numbered from the stream's start and
        # mapped onto host time (receipt times only say when a read found the frames).
        self._numbering = StreamNumbering(FRAME_PERIOD_S)
        self._rejected_frames = 0  # frames that failed their CRC since the last valid one
        self._rows: list[tuple[float, tuple[int, ...], bool, bool]] = []
        saturation = (round(config.range_n * FORCE_COUNTS_PER_N),
                      round(config.range_nm * TORQUE_COUNTS_PER_NM))
        self._saturation_counts = saturation

    def _default_port(self, transport: ByteTransport | None, clock: Clock | None) -> DevicePort:
        config, robot = self.config, self._robot
        if transport is not None or clock is not None or not config.emulated:
            return port_for(config.port, transport=transport, clock=clock)
        start = 0.0 if robot is None else float(robot.truth_time_s)
        return emulated_port(
            config, self.context.rng,
            truth=None if robot is None else robot.physical_truth,
            follow=None if robot is None else (lambda: float(robot.truth_time_s)),
            start_s=start - _EMULATED_LEAD_S - config.tare_s,
        )

    @property
    def model(self) -> Ft300Model | None:
        """The emulated device (``port: emulated``)."""
        port = self.port
        model = port.model if isinstance(port, EmulatedPort) else None
        return model if isinstance(model, Ft300Model) else None

    @property
    def emulator(self) -> PtyEmulator | None:
        """The emulator's pseudo-terminal (``port: emulated``, once configured)."""
        return self.port.emulator if isinstance(self.port, EmulatedPort) else None

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
        # A live port looks once; a paced one every POLL_S up to the simulation's time, as
        # a live driver polls: watchdogs, recovery and receipt times run in device time.
        for _ in self.port.poll_times(FRAME_PERIOD_S, POLL_S):
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
        self._open()
        self._block(self._jam())
        self.device_info = self._identify()

    def on_activate(self) -> None:
        if self._transport is None or not self._transport.is_open:
            self._open()
        self._block(self._start_stream())
        if self.config.tare_s > 0:
            self.tare(wait=True)
        self._rows.clear()  # what came during the handshake and the tare is not data

    def on_deactivate(self) -> None:
        transport = self._transport
        self._streaming = False
        if transport is not None and transport.is_open:
            transport.write(JAM_BYTES)
            # Let the bytes reach the device (and a clock-paced emulator hear them).
            self.port.elapse(POLL_S)

    def on_cleanup(self) -> None:
        if self._transport is not None:
            self._transport.close()
        self.port.stop()

    def recovery_steps(self, error: Exception) -> Iterator[None]:
        """Reconnect (after a link error), jam, restart the stream: in steps that never
        wait, one per look at the port (see :meth:`DeviceLifecycle.begin_recovery`)."""
        transport = self._transport
        if isinstance(error, TransportError) or transport is None or not transport.is_open:
            yield from self._reconnect()
        # Frames of the lost stream that arrive while the jam silences it are discarded:
        # they are the frames the stream's sequence lost.
        yield from self._jam(count_discarded=True)
        yield from self._start_stream()

    def on_recover(self, error: Exception) -> None:
        self._block(self.recovery_steps(error))

    def _block(self, steps: Steps[T] | Iterator[None]) -> T | None:
        """Run steps to the end, pausing one poll between them (the handshake before the
        loop starts, where waiting is what the caller asked for)."""
        while True:
            try:
                next(steps)
            except StopIteration as stop:
                result: T | None = stop.value
                return result
            self.port.elapse(POLL_S)

    def _wait(self, seconds: float) -> Steps[None]:
        """Steps until ``seconds`` have passed on the clock."""
        deadline = self.clock.now() + seconds
        while self.clock.now() < deadline:
            yield

    # -- link --------------------------------------------------------------------------------

    def _open(self) -> None:
        if self._transport is None:
            self._transport = self.port.transport(baudrate=self.config.baudrate)
        self._transport.open()
        self._parser.reset()

    def _link(self) -> ByteTransport:
        if self._transport is None:
            raise TransportError(f"{self.config.port} is not open")
        return self._transport

    def _reconnect(self) -> Steps[None]:
        """Close and reopen the port, a growing delay before each attempt."""
        if self._transport is not None:
            self._transport.close()
        last: Exception | None = None
        for delay in Backoff(attempts=self.config.reconnect_attempts):
            yield from self._wait(delay)
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

    def _jam(self, count_discarded: bool = False) -> Steps[None]:
        """Silence a running stream: 0xFF bursts until no byte comes for ``byte_timeout_s``.
        With ``count_discarded``, the stream's frames discarded meanwhile are dropped
        samples."""
        link = self._link()
        self._streaming = False
        self._parser.reset()
        for _ in range(self.config.jam_attempts):
            link.write(JAM_BYTES)
            if (yield from self._await_silence(count_discarded)):
                yield from self._wait(_JAM_SETTLE_S)
                link.reset_input()
                self._parser.reset()
                return
        raise ProtocolError(
            f"the stream on {self.config.port} did not stop after {self.config.jam_attempts} "
            "jams (0xFF bursts)"
        )

    def _await_silence(self, count_discarded: bool) -> Steps[bool]:
        clock = self.clock
        quiet_s = self.config.byte_timeout_s
        start = last = clock.now()
        listen = max(_JAM_LISTEN_S, 4 * quiet_s)
        # Bounded in time; the count only guards a clock that does not move.
        for _ in range(_MAX_STEPS):
            yield
            data = self._link().read_available()
            now = clock.now()
            if data:
                self.health.bytes += len(data)
                if count_discarded:
                    self.health.dropped_samples += len(self._parser.feed(data))
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
            self.port.elapse(POLL_S)
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

    def _start_stream(self) -> Steps[None]:
        """Write 0x0200 to register 410; accept the echo, or stream frames when it is lost."""
        self._numbering.restart()  # a new stream: its frames count from zero again
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
            for _ in range(_MAX_STEPS):
                yield
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
        """One look at the port: a step of a recovery under way, or parse, deliver and run
        the watchdogs (starting a recovery when they fire). Never waits."""
        if self.recovering:
            self.continue_recovery()
            return
        now = self.clock.now()
        silent_since = self._last_byte_s
        try:
            data = self._read_link()
        except TransportError as exc:
            self._lose_stream(now, exc)
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
            self._lose_stream(now, TimeoutError(
                f"no valid frame from {self.config.port} for {now - self._last_frame_s:.3f} s"
            ))

    def _lose_stream(self, now: float, error: Exception) -> None:
        """The stream is gone: recover (its frames that still arrive are counted lost)."""
        self._numbering.restart()
        self._streaming = False
        self.begin_recovery(error)
        self.continue_recovery()

    def _accept(self, frames: list[bytes], now: float, silent_s: float = 0.0) -> None:
        self._last_frame_s = now
        n = len(frames)
        if not n:
            return
        rejected, self._rejected_frames = self._rejected_frames, 0
        missing = self._numbering.missing
        times = self._numbering.times(n, now, rejected, silent_s)
        self.health.dropped_samples += self._numbering.missing - missing
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
            self.port.elapse(POLL_S)
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
