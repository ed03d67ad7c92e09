"""The run's clock: one time base and one control period for every stream of a run.

A run owns one :class:`RunClock` and hands it to every component in its
:class:`~hapticframe.kinds.BuildContext` (``context.clock``). In a closed loop it reads the
robot's time (the timestamp of the robot's latest state); in an open loop (no robot) it
advances by one control period per read of the sensors. A software sensor (a simulation, a
synthetic source) takes its sample times from it in one line::

    times = self.context.clock.due_times(rate_hz, after_s=self._last_t)

so that its stream keeps step with the robot whatever the read size. A device driver
stamps samples on the host's clock instead and keeps step by reading what is due now.
The run checks every stream against this clock (see ``docs/plugin-authoring.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["DEFAULT_CONTROL_PERIOD_S", "RunClock"]

#: The control period of a clock nobody configured (100 Hz, the sandbox robot's rate).
DEFAULT_CONTROL_PERIOD_S = 0.01
#: Slack on comparing a sample time on a rate's grid with the clock's time: the two are
#: computed in different orders in floating point.
_GRID_EPS = 1e-9


class RunClock:
    """The time a run's streams keep step with, and its control period.

    Parameters
    ----------
    period_s : float
        The control period: the robot's (``1 / control_rate_hz``), or an open loop's
        ``run.live_tick_s``. Positive and finite.
    start_s : float
        The clock's time before the first period (0: a simulated robot's start).

    Notes
    -----
    The clock moves either by :meth:`advance` (an open loop, the conformance kit) or, after
    :meth:`follow`, with a time source (a closed loop: the robot's latest state time). Advanced
    by hand it never goes back; a source takes it where the source is (a robot rewound to
    replay look-ahead steps one at a time takes it back to those steps).
    """

    __slots__ = ("_now_s", "_period_s", "_source", "_start_s")

    def __init__(self, period_s: float = DEFAULT_CONTROL_PERIOD_S, start_s: float = 0.0) -> None:
        period = float(period_s)
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"RunClock: period_s must be positive and finite, got {period_s!r}")
        start = float(start_s)
        if not math.isfinite(start):
            raise ValueError(f"RunClock: start_s must be finite, got {start_s!r}")
        self._period_s = period
        self._start_s = start
        self._now_s = start
        self._source: Callable[[], float] | None = None

    @property
    def period_s(self) -> float:
        """The control period, in seconds."""
        return self._period_s

    @property
    def start_s(self) -> float:
        """The clock's time before the first control period."""
        return self._start_s

    @property
    def follows(self) -> bool:
        """True when a time source moves the clock (a closed loop's robot)."""
        return self._source is not None

    def now_s(self) -> float:
        """The run's time now: the robot's latest state time, or the periods advanced."""
        if self._source is not None:
            # The source's time as it is: a robot rewound for a look-ahead replay takes the
            # clock back with it (the replayed steps are the run's time again).
            now = float(self._source())
            if math.isfinite(now):
                self._now_s = now
        return self._now_s

    def advance(self, periods: int = 1) -> float:
        """Move the clock on by ``periods`` control periods (an open loop's read); returns
        the new time. A clock that follows a time source refuses (its source moves it)."""
        if self._source is not None:
            raise RuntimeError("this clock follows the robot's time: it is not advanced by hand")
        if periods < 0:
            raise ValueError(f"a clock never goes back (periods={periods})")
        # On the grid of periods from the start, so that 10^6 reads do not accumulate error.
        ticks = round((self._now_s - self._start_s) / self._period_s) + periods
        self._now_s = self._start_s + ticks * self._period_s
        return self._now_s

    def follow(self, source: Callable[[], float], period_s: float | None = None) -> None:
        """Read the time from ``source`` from now on (the run hands in its robot's state
        time); ``period_s`` replaces the control period (the robot's)."""
        self._source = source
        if period_s is not None:
            period = float(period_s)
            if not (math.isfinite(period) and period > 0):
                raise ValueError(
                    f"RunClock: period_s must be positive and finite, got {period_s!r}"
                )
            self._period_s = period

    def due_times(self, rate_hz: float, after_s: float | None = None) -> NDArray[np.float64]:
        """The times of the samples a stream at ``rate_hz`` owes since ``after_s``.

        The samples lie on the grid ``start_s + k / rate_hz`` (k = 1, 2, ...), after
        ``after_s`` (None: the clock's start) and at or before :meth:`now_s`. A sensor that
        stamps its samples with these times keeps step with the robot at any read size: a
        read between two grid points owes nothing, one after several owes several.
        """
        rate = float(rate_hz)
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"due_times: rate_hz must be positive and finite, got {rate_hz!r}")
        start = self._start_s
        after = start if after_s is None else max(float(after_s), start)
        first = math.floor((after - start) * rate + _GRID_EPS) + 1
        last = math.floor((self.now_s() - start) * rate + _GRID_EPS)
        if last < first:
            return np.empty(0)
        return start + np.arange(first, last + 1, dtype=np.float64) / rate

    def __repr__(self) -> str:
        source = "following a time source" if self._source is not None else "advanced by hand"
        return f"<RunClock now={self.now_s():.6g} s period={self._period_s:g} s, {source}>"
