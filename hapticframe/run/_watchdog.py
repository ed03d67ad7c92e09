"""The stall watchdog: a live run's force-stream check that a stuck device call cannot stop.

The run loop's own stall check (:class:`~hapticframe.run._safety.SafetyMonitor`) runs between
ticks. While a tick is stuck inside a device call — a driver that blocks, an adapter that
hangs in a write — no check runs, and a real robot keeps moving towards its last target.
In a run with a live device, :class:`StallWatchdog` watches the same thing from a thread on
the host's monotonic clock: while a movement is under way and no valid force sample has been
committed for the stall time plus one control period (the loop's own check, when it runs,
halts first), it halts the moving robot once, with reason ``force_stream_stalled``, and
records that it did. Simulated and emulated runs need none: a call there takes no
simulation time.

``Robot.halt`` is then called from the watchdog's thread: a robot whose halt talks to a bus
that the loop may be using at that moment serialises it itself.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from hapticframe.kinds import Robot

__all__ = ["StallWatchdog"]


class StallWatchdog:
    """Halts the moving robot when the force stream stays silent while the loop is stuck.

    Parameters
    ----------
    stall_s : float
        ``run.force_stall_s``.
    record : callable
        ``record(robot, silent_s)`` once the watchdog halted ``robot`` (the safety halt
        record; called from the watchdog's thread).
    clock : callable, optional
        Host monotonic seconds (tests replace it).
    """

    def __init__(
        self,
        stall_s: float,
        record: Callable[[Robot, float], Any],
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.stall_s = stall_s
        self._record = record
        self._clock = clock
        self._lock = threading.Lock()
        self._robot: Robot | None = None
        self._grace_s = 0.0
        self._last_s = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        #: Halts the watchdog made (robot ids).
        self.fired: list[str] = []

    def start(self) -> StallWatchdog:
        self._thread = threading.Thread(target=self._watch, name="hapticframe stall watchdog",
                                        daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def arm(self, robot: Robot) -> None:
        """A movement of ``robot`` begins: the silence counts from now."""
        with self._lock:
            self._robot = robot
            self._grace_s = 1.0 / float(robot.control_rate_hz)
            self._last_s = self._clock()

    def fed(self) -> None:
        """A valid force sample was committed."""
        with self._lock:
            self._last_s = self._clock()

    def disarm(self) -> None:
        """The movement ended (or the loop halted it itself)."""
        with self._lock:
            self._robot = None

    def _watch(self) -> None:
        while not self._stop.wait(min(0.01, self.stall_s / 10)):
            with self._lock:
                robot = self._robot
                silent_s = self._clock() - self._last_s
                if robot is None or silent_s < self.stall_s + self._grace_s:
                    continue
                self._robot = None  # once per movement
            try:
                robot.halt("force_stream_stalled")
            finally:
                self.fired.append(robot.id)
                self._record(robot, silent_s)
