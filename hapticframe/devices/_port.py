"""Device ports: what a driver is handed — its byte link, its clock, and how far a read goes.

A driver never asks whether its device is real or emulated, as an httpx client never asks
which transport it has. It asks its :class:`DevicePort`:

- :meth:`DevicePort.transport` — the byte link (a :class:`SerialTransport` on a device path
  or an emulator's pseudo-terminal, or a link given in a test);
- :attr:`DevicePort.clock` — the time base samples are stamped with;
- :meth:`DevicePort.read_until` — the time one ``read()`` covers: *now* on a live port, the
  simulation's time (or one period further) on a paced one;
- :meth:`DevicePort.wait_until` / :meth:`DevicePort.elapse` — let time pass: a paced port
  moves its fake clock (and the emulator serves what is due), a live port returns at once
  from ``wait_until`` (a read only does what is due now, it never waits) and really sleeps
  in ``elapse`` (a handshake's pause).

:class:`SerialPort` is the live one. :class:`PacedPort` wraps a given link on a clock that
the port itself moves (a :class:`FakeClock`), and :class:`EmulatedPort` puts a
:class:`DeviceModel` behind a real pseudo-terminal that the driver opens exactly as it opens
hardware. :func:`port_for` picks one from what a driver was given.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe.devices._clock import Clock, FakeClock, MonotonicClock
from hapticframe.devices._emulator import DeviceModel, PtyEmulator
from hapticframe.devices._faults import FaultSchedule
from hapticframe.devices._transport import ByteTransport, SerialTransport

__all__ = ["DevicePort", "EmulatedPort", "LinkPort", "PacedPort", "SerialPort", "port_for"]


class DevicePort:
    """Base of the ports: a link, a clock, and the time a read covers.

    Parameters
    ----------
    clock : Clock
    name : str
        What messages call the port (the configured path, or ``emulated``).
    """

    #: True when the device is real hardware and time is the wall clock's.
    live: bool = True

    def __init__(self, clock: Clock, name: str) -> None:
        self.clock = clock
        self.name = name

    # --- link ------------------------------------------------------------------------------
    def start(self) -> None:
        """Bring up what the link needs (an emulator); idempotent."""

    def stop(self) -> None:
        """Release what :meth:`start` brought up; idempotent, never raises."""

    @property
    def path(self) -> str:
        """What a serial library opens (a device path or a pty's path)."""
        return self.name

    def transport(self, *, baudrate: int, **serial_kwargs: Any) -> ByteTransport:
        """A new, closed byte link to the device."""
        self.start()
        return SerialTransport(self.path, baudrate=baudrate, **serial_kwargs)

    # --- time ------------------------------------------------------------------------------
    def read_until(self, span_s: float) -> float:
        """The time up to which one ``read()`` looks at the device (a live port: now)."""
        return self.clock.now()

    def wait_until(self, t: float) -> None:
        """Let time pass until ``t`` where the port owns time; a live port returns at once."""

    def elapse(self, seconds: float) -> None:
        """Let ``seconds`` pass (a handshake's pause, a backoff before the loop starts)."""
        self.clock.sleep(seconds)

    def poll_times(self, span_s: float, step_s: float) -> Iterator[float]:
        """The times at which one ``read()`` looks at its device: now, then every ``step_s``
        up to :meth:`read_until` (``span_s``) where the port owns time. A live port yields
        now only: the read does what is due and returns; it never waits."""
        until = self.read_until(span_s)
        now = self.clock.now()
        yield now
        for _ in range(_bounded_steps(now, until, step_s)):
            now = self.clock.now()
            if now >= until:
                return
            self.wait_until(min(until, now + step_s))
            yield self.clock.now()


class SerialPort(DevicePort):
    """A real serial device (``/dev/ttyUSB0``, ``/dev/serial/by-id/...``, a pyserial URL) on
    the host's monotonic clock."""

    live = True

    def __init__(self, url: str, *, clock: Clock | None = None) -> None:
        super().__init__(MonotonicClock() if clock is None else clock, url)


class PacedPort(DevicePort):
    """A link on a :class:`FakeClock` that the port moves: deterministic, not wall-paced.

    Parameters
    ----------
    clock : FakeClock
    link : ByteTransport or None, optional
        The link to hand out (an :class:`~hapticframe.devices.EmulatedTransport` in a
        test); None for a subclass that makes its own.
    follow : callable or None, optional
        The simulation time a read catches up to (a robot's ``truth_time_s``); without it
        each read covers ``span_s`` of device time.
    name : str, optional
    """

    live = False

    def __init__(
        self,
        clock: FakeClock,
        link: ByteTransport | None = None,
        *,
        follow: Callable[[], float] | None = None,
        name: str = "emulated",
    ) -> None:
        super().__init__(clock, name)
        self.fake_clock = clock
        self._link = link
        self.follow = follow

    def transport(self, *, baudrate: int, **serial_kwargs: Any) -> ByteTransport:
        if self._link is None:
            return super().transport(baudrate=baudrate, **serial_kwargs)
        return self._link

    def read_until(self, span_s: float) -> float:
        if self.follow is not None:
            return float(self.follow())
        return self.clock.now() + span_s

    def wait_until(self, t: float) -> None:
        self.fake_clock.advance_to(t)


class EmulatedPort(PacedPort):
    """A device model behind a real pseudo-terminal, paced by a :class:`FakeClock`.

    The driver opens :attr:`path` with the same code as a device path (pyserial,
    dynamixel-sdk); the path is a symlink in a private directory that stays put across a
    replug, as ``/dev/serial/by-id/...`` does.

    Parameters
    ----------
    model : DeviceModel
    clock : FakeClock
    faults : FaultSchedule or None, optional
        Byte-level faults of the link (the model takes its own in its constructor).
    follow : callable or None, optional
        See :class:`PacedPort`.
    link_name : str, optional
        The symlink's name (``ft300``, ``ttyDXL``).
    thread : bool or None, optional
        Passed to :class:`PtyEmulator` (True for a host library that blocks on replies).
    fragment_rng : numpy.random.Generator or None, optional
        Passed to :class:`PtyEmulator` (the random choices of byte faults).
    """

    def __init__(
        self,
        model: DeviceModel,
        clock: FakeClock,
        *,
        faults: FaultSchedule | None = None,
        follow: Callable[[], float] | None = None,
        link_name: str = "tty",
        thread: bool | None = None,
        fragment_rng: np.random.Generator | None = None,
    ) -> None:
        super().__init__(clock, None, follow=follow, name="emulated")
        self.model = model
        self.faults = faults
        self.link_name = link_name
        self.thread = thread
        self.fragment_rng = fragment_rng
        self.emulator: PtyEmulator | None = None
        self._dir: Path | None = None

    def start(self) -> None:
        if self.emulator is not None:
            return
        self._dir = Path(tempfile.mkdtemp(prefix=f"hapticframe-{self.link_name}-"))
        self.emulator = PtyEmulator(
            self.model, clock=self.clock, faults=self.faults,
            link_path=self._dir / self.link_name, thread=self.thread,
            fragment_rng=self.fragment_rng,
        ).start()

    def stop(self) -> None:
        if self.emulator is not None:
            self.emulator.stop()
            self.emulator = None
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    @property
    def path(self) -> str:
        self.start()
        assert self.emulator is not None
        return self.emulator.path

    def wait_until(self, t: float) -> None:
        self.fake_clock.advance_to(t)
        if self.emulator is not None and self.thread:
            self.emulator.pump()  # a threaded emulator: serve at the new time at once

    def elapse(self, seconds: float) -> None:
        self.wait_until(self.clock.now() + seconds)


def port_for(
    name: str,
    *,
    transport: ByteTransport | None = None,
    clock: Clock | None = None,
    follow: Callable[[], float] | None = None,
) -> DevicePort:
    """The port for a driver given an optional link and clock (tests, a lab's adapter).

    A :class:`FakeClock` makes a :class:`PacedPort` (the port moves it, each read covers
    ``follow()`` or one span); any other clock, or none, a live port on ``transport`` or on
    the serial device ``name``.
    """
    if isinstance(clock, FakeClock):
        return PacedPort(clock, transport, follow=follow, name=name)
    if transport is None:
        return SerialPort(name, clock=clock)
    return LinkPort(transport, MonotonicClock() if clock is None else clock, name)


class LinkPort(DevicePort):
    """A live port over a given link (a lab's own adapter class): the port never moves its
    clock, each read looks once. A test may give it a :class:`FakeClock` that the test
    moves, to play a host whose reads come when it likes."""

    def __init__(self, link: ByteTransport, clock: Clock, name: str) -> None:
        super().__init__(clock, name)
        self._link = link

    def transport(self, *, baudrate: int, **serial_kwargs: Any) -> ByteTransport:
        return self._link


def _bounded_steps(start_s: float, until_s: float, step_s: float) -> int:
    """How many ``step_s`` steps take a clock from ``start_s`` to ``until_s`` (a loop bound)."""
    if not until_s > start_s:
        return 0
    return math.ceil((until_s - start_s) / step_s) + 1
