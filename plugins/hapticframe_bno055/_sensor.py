"""The BNO055 sensor component: a polled UART driver with bounded retries and recovery.

Each poll sends one burst read of the data registers (0x08..0x35) and waits for the reply
in small ``clock.sleep`` steps, bounded by ``reply_timeout_s``. EE 07 (bus overrun) and
EE 0A (character timeout) are answered by resending, as the application note says; so are
timeouts and malformed replies, up to ``max_retries``. The input is drained before every
request, and a reply is accepted only when exactly its bytes arrived (the protocol has no
checksum: a stale or garbage byte anywhere rejects the exchange). No valid reply for
``watchdog_s``, a disconnect, or data registers that read zero (the chip reset to CONFIG
mode) start a recovery: reopen with backoff and reconfigure, at most ``max_recoveries`` times
in a row before :class:`~hapticframe.devices.DeviceError`. The recovery runs in steps, one
per poll slot: a read waits for one request's reply at most, never for the backoff.

The driver talks to a :class:`~hapticframe.devices.DevicePort`: a serial device, or with
``port: emulated`` a :class:`Bno055Model` behind a real pseudo-terminal whose fake clock
follows the simulation time of the robot input. The code path is the same for both.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from hapticframe.devices import (
    Backoff,
    ByteTransport,
    Clock,
    DeviceError,
    DeviceHealth,
    DeviceLifecycle,
    DevicePort,
    EmulatedPort,
    FaultSchedule,
    LifecycleState,
    PtyEmulator,
    SerialPort,
    TransportError,
)
from hapticframe.geometry import rotation_matrix_from_wxyz
from hapticframe.kinds import (
    BuildContext,
    ChannelInfo,
    Component,
    PhysicalTruthSource,
    SampleBatch,
    Sensor,
)

from ._config import Bno055SensorConfig
from ._emulator import GRAVITY_M_PER_S2, Bno055Model, emulated_port
from ._protocol import (
    CHIP_ID_VALUE,
    DATA_LENGTH,
    DATA_START,
    RETRYABLE_STATUSES,
    SYS_TRIGGER_RESET,
    UNIT_SEL_SI,
    OperationMode,
    Register,
    Reply,
    Status,
    decode_data_block,
    encode_read,
    encode_write,
    parse_reply,
    status_name,
)

__all__ = ["BAUDRATE", "CHANNELS", "Bno055Health", "Bno055ProtocolError", "Bno055Sensor"]

BAUDRATE = 115_200
#: Channel name → shape and unit (every channel runs at the configured rate).
CHANNELS: Mapping[str, tuple[tuple[int, ...], str]] = MappingProxyType({
    "acceleration_m_per_s2": ((3,), "m/s^2"),
    "linear_acceleration_m_per_s2": ((3,), "m/s^2"),
    "gravity_m_per_s2": ((3,), "m/s^2"),
    "angular_velocity_rad_per_s": ((3,), "rad/s"),
    "orientation_wxyz": ((4,), "1"),
    "calibration": ((4,), "1"),
})
_FUSED = ("linear_acceleration_m_per_s2", "gravity_m_per_s2", "orientation_wxyz")
_MODES = {"ndof": OperationMode.NDOF, "accgyro": OperationMode.ACCGYRO}
_TO_CONFIG_S = 0.019
_FROM_CONFIG_S = 0.007
_RESET_S = 0.650
#: A read that finds more polls due than this skips ahead (counted as dropped samples).
_MAX_POLLS_PER_READ = 10_000


@dataclass
class Bno055Health(DeviceHealth):
    """:class:`~hapticframe.devices.DeviceHealth` plus the BNO055's status replies.

    Attributes
    ----------
    bus_overruns : int
        EE 07 replies (each answered by a resend).
    char_timeouts : int
        EE 0A replies (each answered by a resend).
    status_errors : int
        Other EE replies that were not the expected answer (READ_FAIL, WRITE_FAIL...).
    framing_errors : int
        Replies with a wrong start byte, a wrong length byte, or stale or trailing bytes.
    """

    bus_overruns: int = 0
    char_timeouts: int = 0
    status_errors: int = 0
    framing_errors: int = 0


class Bno055ProtocolError(RuntimeError):
    """A request got no usable answer within its retries."""


class _DeviceWasReset(RuntimeError):
    """The data registers read zero: the chip is in CONFIG mode (it reset or rebooted)."""


class Bno055Sensor(Sensor, DeviceLifecycle):
    """A Bosch BNO055 IMU polled over its UART.

    Parameters
    ----------
    config : Bno055SensorConfig
    context : BuildContext
        ``inputs`` may hold one robot implementing
        :class:`hapticframe.kinds.PhysicalTruthSource`; it drives the emulated device (a
        real port ignores it).
    port : DevicePort, optional
        Where the link and the clock come from (default: ``config.port``, a serial device,
        or the emulator for ``emulated``, whose clock follows the robot's simulation time).
    """

    def __init__(
        self, config: Bno055SensorConfig, context: BuildContext, *,
        port: DevicePort | None = None,
    ) -> None:
        super().__init__(config, context)
        self.config: Bno055SensorConfig = config
        self.max_recoveries = config.max_recoveries
        self._health = Bno055Health()
        self._truth_source = self._find_truth_source(context.inputs) if config.emulated else None
        self._period_s = 1.0 / config.rate_hz
        self._mode = _MODES[config.mode]
        if port is None:
            port = self._default_port()
        self.port: DevicePort = port
        self.live = port.live
        self._clock: Clock = port.clock
        self._channels = MappingProxyType({
            name: ChannelInfo(shape=shape, unit=unit, rate_hz=config.rate_hz)
            for name, (shape, unit) in CHANNELS.items()
        })
        self._data_request = encode_read(DATA_START, DATA_LENGTH)
        self._transport: ByteTransport | None = None
        self._next_poll_s = 0.0
        self._last_valid_s = 0.0
        self._last_t = -math.inf
        self._reply_time_s = 0.0

    def _default_port(self) -> DevicePort:
        if not self.config.emulated:
            return SerialPort(self.config.port)
        robot = self._truth_source
        # The emulated device's clock is the simulation's: it starts at the robot's time.
        return emulated_port(
            self.config, self.context.rng,
            truth=None if robot is None else robot.physical_truth,
            follow=None if robot is None else (lambda: float(robot.truth_time_s)),
            start_s=0.0 if robot is None else float(robot.truth_time_s),
            baudrate=BAUDRATE,
        )

    def _find_truth_source(self, inputs: Mapping[str, Component]) -> PhysicalTruthSource | None:
        if not inputs:
            return None
        if len(inputs) != 1:
            raise ValueError(
                f"sensor {self.id!r} (type 'bno055') takes at most one input, the robot it is "
                f"mounted on; got {list(inputs)}"
            )
        (name, robot), = inputs.items()
        if not isinstance(robot, PhysicalTruthSource):
            raise ValueError(
                f"sensor {self.id!r} (type 'bno055', port: emulated) needs its robot input to "
                f"expose its physical truth (hapticframe.kinds.PhysicalTruthSource: "
                f"physical_truth(t) and truth_time_s); input {name!r} "
                f"({type(robot).__name__}) does not"
            )
        return robot

    # --- component interface -------------------------------------------------------------
    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def health(self) -> Bno055Health:
        """Counters of this device (status replies included)."""
        return self._health

    @property
    def clock(self) -> Clock:
        """The host clock samples are stamped with (the port's)."""
        return self._clock

    @property
    def model(self) -> Bno055Model | None:
        """The emulated chip (None on a real port)."""
        model = self.port.model if isinstance(self.port, EmulatedPort) else None
        return model if isinstance(model, Bno055Model) else None

    @property
    def emulator(self) -> PtyEmulator | None:
        """The pseudo-terminal emulator (None on a real port or before configure)."""
        return self.port.emulator if isinstance(self.port, EmulatedPort) else None

    @property
    def faults(self) -> FaultSchedule | None:
        """The emulator's fault schedule (None without faults)."""
        return self.port.faults if isinstance(self.port, EmulatedPort) else None

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    def read(self) -> SampleBatch:
        """One sample per poll due since the previous read (maybe none).

        Raises
        ------
        DeviceError
            When the device is not active (``configure()`` and ``activate()`` come first, as
            a run and the conformance kit do), or stopped answering and bounded recovery
            failed.
        """
        if self.lifecycle_state is not LifecycleState.ACTIVE:
            raise DeviceError(
                f"device {self.id!r} cannot be read: it is {self.lifecycle_state.value}; "
                "configure() and activate() it first",
                device_id=self.id,
            )
        # A live port: the polls due by now. A paced one (emulated): its clock moves to the
        # robot's simulation time, one poll at a time (without a robot: one poll per read).
        target = self.port.read_until(max(0.0, self._next_poll_s - self._clock.now()))
        rows: list[tuple[float, dict[str, np.ndarray], dict[str, bool]]] = []
        polls = 0
        while self._next_poll_s <= target:
            if polls >= _MAX_POLLS_PER_READ:
                self._skip_to(target)
                break
            self.port.wait_until(self._next_poll_s)
            row = self._poll_or_recover()
            polls += 1
            if row is not None:
                rows.append(row)
            self._next_poll_s += self._period_s
            # Polls a recovery's exchanges overran were not due: no device was there.
            self._skip_to(self._clock.now(), count=not self.recovering)
        self.port.wait_until(target)
        return self._batch(rows)

    def _skip_to(self, now_s: float, count: bool = True) -> None:
        """Polls more than one period late are not sent: count them as dropped."""
        late = now_s - self._next_poll_s
        if late > self._period_s:
            missed = math.floor(late / self._period_s)
            self._next_poll_s += missed * self._period_s
            if count:
                self._health.dropped_samples += missed

    def _batch(self, rows: list[tuple[float, dict[str, np.ndarray], dict[str, bool]]]
               ) -> SampleBatch:
        if not rows:
            return SampleBatch.empty(self._channels)
        times = np.array([t for t, _, _ in rows])
        channels = {name: np.stack([values[name] for _, values, _ in rows])
                    for name in self._channels}
        valid = {name: np.array([flags[name] for _, _, flags in rows])
                 for name in self._channels}
        return SampleBatch(times, channels, valid)

    # --- lifecycle hooks -------------------------------------------------------------------
    def on_configure(self) -> None:
        """Start the emulator (emulated), open the port, identify the chip, set CONFIG mode,
        page 0 and the units."""
        try:
            self._open()
            self._initialise()
        except Exception:
            self._close_transport()
            self.port.stop()
            raise

    def on_activate(self) -> None:
        """Select the output mode and start polling."""
        self._select_mode()
        now = self._clock.now()
        self._next_poll_s = now
        self._last_valid_s = now

    def on_deactivate(self) -> None:
        """Back to CONFIG mode (fusion halted), best effort: a gone link is no error."""
        if self._transport is None or not self._transport.is_open:
            return
        try:
            self._write_register(Register.OPR_MODE, OperationMode.CONFIG, retries=0)
        except (Bno055ProtocolError, TransportError):
            pass

    def on_cleanup(self) -> None:
        self._close_transport()
        self.port.stop()

    def on_recover(self, error: Exception) -> None:
        """:meth:`recovery_steps` run to the end (waiting a poll period between steps)."""
        for _ in self.recovery_steps(error):
            self.port.elapse(self._period_s)

    def recovery_steps(self, error: Exception) -> Iterator[None]:
        """Reopen the port with backoff and configure the chip again; raise when it cannot.
        The backoff is waited in steps, one per poll slot (a read never waits for it); an
        attempt itself is a few bounded exchanges."""
        self._close_transport()
        last: Exception = error
        for delay in Backoff(initial_s=0.05, attempts=self.config.reconnect_attempts):
            yield from self._wait_steps(delay, stepping=True)
            try:
                self._open()
                self._health.reconnects += 1
                yield from self._initialise_steps()
                yield
                self._select_mode()
            except (TransportError, Bno055ProtocolError) as exc:
                last = exc
                self._close_transport()
                continue
            now = self._clock.now()
            self._next_poll_s = now
            self._last_valid_s = now
            return
        raise last

    # --- transport -----------------------------------------------------------------------
    def _open(self) -> None:
        transport = self.port.transport(baudrate=BAUDRATE)
        transport.open()
        self._transport = transport

    def _close_transport(self) -> None:
        if self._transport is not None:
            try:
                self._transport.close()
            except OSError:
                pass  # closing a link that is already gone
            self._transport = None

    def _link(self) -> ByteTransport:
        if self._transport is None or not self._transport.is_open:
            raise TransportError(f"device {self.id!r}: the port is not open")
        return self._transport

    # --- requests ----------------------------------------------------------------------
    def _exchange(self, request: bytes, expected_length: int | None) -> Reply | None:
        """Send one request and wait (bounded) for its reply; None on timeout."""
        link = self._link()
        stale = link.read_available()
        if stale:  # an earlier answer that came too late, or noise on the line
            self._health.bytes += len(stale)
            self._health.resyncs += len(stale)
        link.reset_input()
        link.write(request)
        clock = self._clock
        deadline = clock.now() + self.config.reply_timeout_s
        buffer = bytearray()
        while True:
            clock.sleep(self.config.poll_step_s)
            chunk = link.read_available()
            if chunk:
                self._health.bytes += len(chunk)
                buffer += chunk
                reply = parse_reply(bytes(buffer), expected_length)
                if reply is not None:
                    if reply.error is None:
                        self._reply_time_s = clock.now()
                        # One more step: a byte right behind the reply means it was not
                        # the reply alone (stale or garbage bytes around it).
                        clock.sleep(self.config.poll_step_s)
                        extra = link.read_available()
                        if extra:
                            self._health.bytes += len(extra)
                            return Reply(error="trailing_bytes")
                    return reply
            if clock.now() >= deadline:
                return None

    def _request(self, request: bytes, expected_length: int | None, *, retries: int,
                 what: str) -> Reply:
        """A request with resends after EE 07/0A, timeouts and malformed replies.

        Returns the data reply (reads) or the EE 01 reply (writes).

        Raises
        ------
        Bno055ProtocolError
            After the retries, or at once on another status.
        """
        health = self._health
        outcome = "no reply"
        for _ in range(1 + retries):
            reply = self._exchange(request, expected_length)
            if reply is None:
                health.timeouts += 1
                outcome = "no reply"
                continue
            if reply.error is not None:
                health.framing_errors += 1
                outcome = reply.error.replace("_", " ")
                continue
            if reply.status is not None:
                code = reply.status
                if expected_length is None and code == Status.WRITE_SUCCESS:
                    return reply
                outcome = f"status EE {code:02X} ({status_name(code)})"
                if code == Status.BUS_OVER_RUN_ERROR:
                    health.bus_overruns += 1
                elif code == Status.RECEIVE_CHARACTER_TIMEOUT:
                    health.char_timeouts += 1
                else:
                    health.status_errors += 1
                if code in RETRYABLE_STATUSES:
                    continue
                break
            health.frames += 1
            return reply
        raise Bno055ProtocolError(f"device {self.id!r}: {what}: {outcome}")

    def _read_register(self, register: int, length: int, *, what: str) -> bytes:
        reply = self._request(encode_read(register, length), length,
                              retries=self.config.max_retries, what=what)
        assert reply.data is not None
        return reply.data

    def _write_register(self, register: int, value: int, *, retries: int | None = None) -> None:
        self._request(
            encode_write(register, bytes((value,))), None,
            retries=self.config.max_retries if retries is None else retries,
            what=f"write 0x{value:02X} to register 0x{register:02X}",
        )

    def _initialise(self) -> None:
        """Identify the chip and bring it to CONFIG mode, page 0, SI-friendly units."""
        for _ in self._initialise_steps(stepping=False):
            pass

    def _wait_steps(self, seconds: float, stepping: bool) -> Iterator[None]:
        """Let ``seconds`` pass: in steps (a recovery under way), or sleeping (configure)."""
        if not stepping:
            self._clock.sleep(seconds)
            return
        deadline = self._clock.now() + seconds
        while self._clock.now() < deadline:
            yield

    def _initialise_steps(self, stepping: bool = True) -> Iterator[None]:
        """:meth:`_initialise` in steps of at most one request (a recovery's reads never
        wait for more than one reply)."""
        link = self._link()
        if self.config.reset_on_configure:
            # The reset is never acknowledged in UART mode: write it blind and wait.
            link.write(encode_write(Register.SYS_TRIGGER, bytes((SYS_TRIGGER_RESET,))))
            yield from self._wait_steps(_RESET_S, stepping)
        chip_id: int | None = None
        for attempt in range(self.config.chip_id_attempts):
            if attempt:
                yield
            try:
                chip_id = self._read_register(Register.CHIP_ID, 1, what="read CHIP_ID")[0]
                break
            except Bno055ProtocolError:
                continue
        if chip_id is None:
            raise Bno055ProtocolError(
                f"device {self.id!r} on {self.port.name!r} did not answer a CHIP_ID read "
                f"({self.config.chip_id_attempts} attempts): is it a BNO055 in UART mode at "
                f"{BAUDRATE} baud?"
            )
        if chip_id != CHIP_ID_VALUE:
            raise Bno055ProtocolError(
                f"device {self.id!r} on {self.port.name!r} has CHIP_ID 0x{chip_id:02X}, not "
                f"0x{CHIP_ID_VALUE:02X}: not a BNO055"
            )
        yield
        self._write_register(Register.PAGE_ID, 0)
        yield
        self._write_register(Register.OPR_MODE, OperationMode.CONFIG)
        self._clock.sleep(_TO_CONFIG_S)
        yield
        self._write_register(Register.UNIT_SEL, UNIT_SEL_SI)

    def _select_mode(self) -> None:
        self._write_register(Register.OPR_MODE, self._mode)
        self._clock.sleep(_FROM_CONFIG_S)

    # --- polling ----------------------------------------------------------------------------
    def _poll_or_recover(self) -> tuple[float, dict[str, np.ndarray], dict[str, bool]] | None:
        """One poll slot: a step of a recovery under way, or one poll (starting a recovery
        when it fails). DeviceError when the device cannot go on."""
        if self.recovering:
            self.continue_recovery()
            return None
        try:
            return self._poll()
        except (TransportError, Bno055ProtocolError, _DeviceWasReset) as exc:
            self.begin_recovery(exc)
            self.continue_recovery()
            return None

    def _poll(self) -> tuple[float, dict[str, np.ndarray], dict[str, bool]] | None:
        try:
            reply = self._request(self._data_request, DATA_LENGTH,
                                  retries=self.config.max_retries, what="read the data registers")
        except Bno055ProtocolError as exc:
            self._health.dropped_samples += 1
            silent_s = self._clock.now() - self._last_valid_s
            if silent_s > self.config.watchdog_s:
                raise Bno055ProtocolError(
                    f"{exc} — no valid reply for {silent_s:.3f} s (watchdog "
                    f"{self.config.watchdog_s:g} s)"
                ) from exc
            return None
        self._last_valid_s = self._clock.now()
        assert reply.data is not None
        return self._sample(reply.data)

    def _sample(self, data: bytes) -> tuple[float, dict[str, np.ndarray], dict[str, bool]]:
        block = decode_data_block(data, UNIT_SEL_SI)
        if not np.any(block.acceleration_m_per_s2):
            # A resting or moving accelerometer never reads exactly zero on all axes: the
            # chip is in CONFIG mode (it reset). Configure it again.
            self._health.invalid_samples += 1
            raise _DeviceWasReset(
                f"device {self.id!r}: the data registers read zero (the chip is in CONFIG mode)"
            )
        values = {
            "acceleration_m_per_s2": block.acceleration_m_per_s2,
            "linear_acceleration_m_per_s2": block.linear_acceleration_m_per_s2,
            "gravity_m_per_s2": block.gravity_m_per_s2,
            "angular_velocity_rad_per_s": block.angular_velocity_rad_per_s,
            "orientation_wxyz": block.orientation_wxyz,
            "calibration": block.calibration,
        }
        flags = dict.fromkeys(self._channels, True)
        if self._mode == OperationMode.NDOF:
            fused_ok = self._fusion_plausible(block.orientation_wxyz, block.gravity_m_per_s2,
                                              int(block.calibration[0]))
            if not fused_ok:
                self._health.invalid_samples += 1
        else:
            fused_ok = False  # ACCGYRO computes no fusion: these channels do not exist
        for name in _FUSED:
            if not fused_ok:
                flags[name] = False
                values[name] = np.full_like(values[name], np.nan)
        t = self._reply_time_s
        if t <= self._last_t:
            t = math.nextafter(self._last_t, math.inf)
        self._last_t = t
        return t, values, flags

    def _fusion_plausible(self, quaternion: np.ndarray, gravity: np.ndarray,
                          system_level: int) -> bool:
        """The fused outputs pass the unit-norm, |g| and consistency checks."""
        config = self.config
        if system_level < config.min_system_calibration:
            return False
        norm = float(np.linalg.norm(quaternion))
        if abs(norm - 1.0) > config.quaternion_norm_tolerance:
            return False
        if abs(float(np.linalg.norm(gravity)) - GRAVITY_M_PER_S2) > (
            config.gravity_tolerance_m_per_s2
        ):
            return False
        if config.check_gravity_against_quaternion:
            expected = rotation_matrix_from_wxyz(quaternion).T @ np.array(
                [0.0, 0.0, GRAVITY_M_PER_S2]
            )
            if float(np.linalg.norm(expected - gravity)) > config.gravity_tolerance_m_per_s2:
                return False
        return True
