"""Time bases for devices: the host's monotonic clock, a fake clock for tests and simulated
runs, and the estimate of a device clock's offset and drift."""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Clock", "ClockSync", "FakeClock", "MonotonicClock"]


@runtime_checkable
class Clock(Protocol):
    """Host time for a device: monotonic seconds, and a way to wait on it."""

    def now(self) -> float:
        """Seconds on a monotonic time base."""
        ...

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` on this clock."""
        ...


class MonotonicClock:
    """The host's clock: :func:`time.monotonic` and :func:`time.sleep` (live devices)."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class FakeClock:
    """A clock that moves only when told: deterministic tests and simulated runs.

    Listeners are called synchronously, in the caller's thread, after every advance, with the
    new time. That is how emulators are paced: a driver waiting for a reply calls
    ``clock.sleep(dt)``, the clock advances and the emulator's listener services its port
    before ``sleep`` returns.

    Parameters
    ----------
    start_s : float, optional
        The initial time.
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._now = float(start_s)
        self._listeners: list[Callable[[float], None]] = []

    def now(self) -> float:
        return self._now

    def sleep(self, seconds: float) -> None:
        """Same as :meth:`advance`: sleeping on a fake clock moves it."""
        self.advance(seconds)

    def advance(self, seconds: float) -> None:
        """Move forward by ``seconds`` (zero still notifies the listeners) and notify."""
        if not seconds >= 0:
            raise ValueError(f"cannot advance a clock by {seconds} s")
        self._now += seconds
        self._notify()

    def advance_to(self, t: float) -> None:
        """Move to time ``t``; a time in the past is a no-op (the clock never goes back)."""
        if t > self._now:
            self._now = float(t)
            self._notify()

    def add_listener(self, fn: Callable[[float], None]) -> None:
        """Call ``fn(now)`` after every advance."""
        self._listeners.append(fn)

    def remove_listener(self, fn: Callable[[float], None]) -> None:
        """Stop calling ``fn`` (a no-op when it is not registered)."""
        if fn in self._listeners:
            self._listeners.remove(fn)

    def _notify(self) -> None:
        now = self._now
        for fn in tuple(self._listeners):  # a listener may remove itself
            fn(now)


class ClockSync:
    """Maps a device's clock (or sequence counter) onto host time, and counts missed samples.

    The model is ``host = offset + (1 + drift) * device``. The drift is the least-squares
    slope over the last ``window`` pairs (device time, host receipt time), trusted once they
    span ``min_span_s`` of device time and bounded by ``max_drift`` (samples read in bursts
    would otherwise fake a slope). Receipt times only ever lag the true time (transport
    latency, reads in batches), so the offset is the lower envelope: the least lag in the
    window, which the estimate approaches as soon as one sample arrives promptly.

    Parameters
    ----------
    nominal_period_s : float or None, optional
        The device's sample period. With it, :meth:`gap` takes device times; without it,
        sequence numbers (consecutive integers).
    window : int, optional
        Pairs kept for the fit (at 100 Hz, 200 pairs = the last 2 s).
    min_span_s : float, optional
        Device time the window must span before the drift is estimated (0 until then).
    max_drift : float, optional
        Largest drift believed (crystal clocks stay within a few hundred ppm).
    """

    def __init__(
        self,
        nominal_period_s: float | None = None,
        *,
        window: int = 200,
        min_span_s: float = 1.0,
        max_drift: float = 1e-3,
    ) -> None:
        if nominal_period_s is not None and not nominal_period_s > 0:
            raise ValueError("nominal_period_s must be positive")
        if window < 2:
            raise ValueError("window must hold at least two pairs")
        self.nominal_period_s = nominal_period_s
        self.window = window
        self.min_span_s = min_span_s
        self.max_drift = max_drift
        self._pairs: deque[tuple[float, float]] = deque(maxlen=window)
        self._offset = math.nan
        self._slope = 1.0
        self._last: float | None = None
        self._gaps = 0

    @property
    def offset_s(self) -> float:
        """Host time at device time zero (NaN before the first update)."""
        return self._offset

    @property
    def drift(self) -> float:
        """How much faster the host clock runs than the device's (s/s; 0 = same rate)."""
        return self._slope - 1.0

    @property
    def gaps(self) -> int:
        """Samples missed so far, as counted by :meth:`gap`."""
        return self._gaps

    def reset(self) -> None:
        """Forget the fit and the last sample (a device that restarted its clock)."""
        self._pairs.clear()
        self._offset = math.nan
        self._slope = 1.0
        self._last = None

    def update(self, device_time_s: float, host_time_s: float) -> float:
        """Add one pair and return the host-time estimate of ``device_time_s``."""
        self._pairs.append((float(device_time_s), float(host_time_s)))
        pairs = np.array(self._pairs, dtype=np.float64)
        device, host = pairs[:, 0], pairs[:, 1]
        slope = 1.0
        if device.max() - device.min() >= self.min_span_s:
            # Centred sums: device times can be large; raw sums would lose precision.
            d0, h0 = device.mean(), host.mean()
            fitted = float(np.dot(device - d0, host - h0)) / float(np.dot(device - d0, device - d0))
            slope = min(max(fitted, 1.0 - self.max_drift), 1.0 + self.max_drift)
        self._slope = slope
        self._offset = float((host - slope * device).min())
        return self._offset + slope * device_time_s

    def host_time(self, device_time_s: float) -> float:
        """The host-time estimate of ``device_time_s`` with the current fit.

        For samples read in a burst, :meth:`update` with all of them first, then map each:
        every sample then benefits from the promptest one.
        """
        return self._offset + self._slope * device_time_s

    def gap(self, seq_or_time: float) -> int:
        """Samples missed between the previous call's value and this one (also counted).

        A repeated or older value (a device restart) counts nothing and restarts the count.
        """
        last, self._last = self._last, float(seq_or_time)
        if last is None or seq_or_time <= last:
            return 0
        step = seq_or_time - last
        if self.nominal_period_s is not None:
            step /= self.nominal_period_s
        missed = max(round(step) - 1, 0)
        self._gaps += missed
        return missed
