"""CAN ports: what the puck host and the Barrett robots are handed — a CAN channel, its
clock, and how a wait lets time pass.

The host and the robots never ask whether their pucks are real or emulated; they ask their
:class:`CanPort`:

- :meth:`CanPort.open` — a python-can bus on the channel (a ``socketcan`` channel, or the
  ``virtual`` channel of a :class:`~._emulator.PuckBus`);
- :attr:`CanPort.clock` — the time base of every wait and every state;
- :meth:`CanPort.frames` — the frames that arrive before a deadline: a live port waits in
  ``bus.recv`` up to the deadline; a paced port takes what has arrived, lets the emulator
  answer what it has had (``clock.sleep(0)``: its listener returns once its reader has
  handled every frame sent), then moves its fake clock to the deadline (the emulator sends
  what is due by then) and takes what came. No real time is spent waiting;
- :meth:`CanPort.wait_until` / :meth:`CanPort.elapse` — let time pass: a paced port moves
  its fake clock, a live port returns at once from ``wait_until`` (real time has passed on
  its own) and really sleeps in ``elapse``.

:class:`CanPort` is the live one; :class:`PacedCanPort` owns a :class:`FakeClock` (a test
gives it the other end of the channel), and :class:`EmulatedCanPort` also brings up the
emulated pucks on a ``virtual`` channel of their own.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator
from typing import Any

import can

from hapticframe.devices import Clock, FakeClock, FaultSchedule, MonotonicClock

from ._emulator import EmulatedPuck, PuckBus

__all__ = ["CanPort", "EmulatedCanPort", "PacedCanPort"]

_CHANNELS = itertools.count()

#: What one receive call looks like: ``recv(timeout_s)``, None when nothing came.
Receive = Callable[[float], "can.Message | None"]


class CanPort:
    """A real CAN channel on the host's monotonic clock.

    Parameters
    ----------
    interface : str
        python-can's interface (``socketcan``, ``pcan``, ...).
    channel : str
        The channel (``can0``).
    bitrate : int or None, optional
        Passed to python-can when given.
    clock : Clock or None, optional
        The monotonic clock by default.
    """

    #: True when the pucks are real hardware and time is the wall clock's.
    live: bool = True

    def __init__(self, interface: str, channel: str, *, bitrate: int | None = None,
                 clock: Clock | None = None) -> None:
        self.interface = interface
        self.channel = channel
        self.bitrate = bitrate
        self.clock: Clock = MonotonicClock() if clock is None else clock

    # --- link ------------------------------------------------------------------------------
    def start(self) -> None:
        """Bring up what the channel needs (the emulated pucks); idempotent."""

    def stop(self) -> None:
        """Release what :meth:`start` brought up; idempotent."""

    def open(self) -> can.BusABC:
        """A new python-can bus on the channel (at configure, and after a link failure).

        Raises
        ------
        can.CanError, OSError, ValueError
            What python-can raises for a channel it cannot open.
        """
        self.start()
        args: dict[str, Any] = {"interface": self.interface, "channel": self.channel}
        if self.bitrate is not None:
            args["bitrate"] = self.bitrate
        return can.Bus(**args)

    # --- time ------------------------------------------------------------------------------
    def frames(self, recv: Receive, deadline: float) -> Iterator[can.Message]:
        """The frames that arrive until ``deadline`` (on :attr:`clock`): each ``recv`` waits
        for real up to the deadline; the iterator ends when one comes back empty after it."""
        while True:
            remaining = deadline - self.clock.now()
            msg = recv(remaining)
            if msg is not None:
                yield msg
                continue
            if remaining <= 0:
                return

    def wait_until(self, t: float) -> None:
        """Let time pass until ``t`` where the port owns time; a live port returns at once."""

    def elapse(self, seconds: float) -> None:
        """Let ``seconds`` pass (a wake-up time, a poll interval, a backoff)."""
        self.clock.sleep(seconds)


class PacedCanPort(CanPort):
    """A channel whose time is a :class:`FakeClock` that the port moves: deterministic.

    Parameters
    ----------
    clock : FakeClock
    interface, channel : str, optional
        What :meth:`open` opens (a ``virtual`` channel that an emulator also opens).
    settle_s : float, optional
        Real time a wait first gives the peer to answer (0: an emulator on this clock answers
        synchronously when the clock moves).
    """

    live = False

    def __init__(self, clock: FakeClock, *, interface: str = "virtual",
                 channel: str = "hapticframe-barrett", settle_s: float = 0.0) -> None:
        super().__init__(interface, channel, clock=clock)
        self.fake_clock = clock
        self.settle_s = settle_s

    def frames(self, recv: Receive, deadline: float) -> Iterator[can.Message]:
        stage = 0  # 0 nothing yet, 1 synced (sleep 0), 2 slept to the deadline
        while True:
            remaining = deadline - self.clock.now()
            msg = recv(self.settle_s if stage == 0 else 0.0)
            if msg is not None:
                yield msg
                continue
            if stage == 0:
                self.fake_clock.sleep(0.0)  # an emulator on this clock answers what it had
                stage = 1
            elif stage == 1 and remaining > 0:
                self.fake_clock.sleep(remaining)
                stage = 2
            else:
                return

    def wait_until(self, t: float) -> None:
        self.fake_clock.advance_to(t)


class EmulatedCanPort(PacedCanPort):
    """Emulated pucks on a ``virtual`` channel of their own, on a :class:`FakeClock` that
    starts at 0 (their fault times are on it).

    Parameters
    ----------
    pucks : callable
        Called once, at :meth:`start`: the pucks and their fault schedule (built then, so
        that the faults draw from the robot's generator when the robot configures).
    name : str
        The channel's prefix (a counter makes each channel unique in the process).
    """

    def __init__(
        self,
        pucks: Callable[[], tuple[list[EmulatedPuck], FaultSchedule | None]],
        *,
        name: str,
    ) -> None:
        super().__init__(FakeClock(0.0), channel=name)
        self._pucks = pucks
        self._name = name
        self.emulator: PuckBus | None = None

    def start(self) -> None:
        if self.emulator is not None:
            return
        pucks, schedule = self._pucks()
        self.channel = f"{self._name}-{next(_CHANNELS)}"
        self.emulator = PuckBus(self.channel, pucks, clock=self.fake_clock,
                                faults=schedule).start()

    def stop(self) -> None:
        if self.emulator is not None:
            self.emulator.stop()
            self.emulator = None
