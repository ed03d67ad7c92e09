"""The drag-ratio detector's arithmetic: the movement's free drag, the CUSUM, the probabilities.

Everything here runs on plain floats, one sample at a time, because every step depends on
the one before (the drag estimate is frozen while the CUSUM holds evidence). The classifier,
its calibration and the bench all call :class:`DragTracker`, so what ``fit`` measured is
what a run does.

Why a CUSUM on the log-ratio, not a threshold on the ratio and its rate: in the engine
world the rise ahead of an object is a slow x1.3-2 over 2.5-3 cm, and the force rate it
makes (0.6-1.8 drag/s at 5 cm/s) is no larger than the sandbox's shear-band sawtooth in free
sand (about 0.3-0.6 drag/s), with sensor noise of up to a third of a shallow drag on top.
What separates a jamming rise from free sand is that it *persists*: the CUSUM integrates the
excess of ``log(f/b)`` over an allowance and forgets every excursion that falls back below
it, so noise and the sawtooth's upper halves rarely reach the level a sustained rise
crosses within a few centimetres. With ``cusum_threshold = 0`` the rule is a plain ratio
threshold at ``exp(drift)``, so ``fit`` can still choose that rule when it is better. The
log makes the rule symmetric in the drag: a force twice the drag counts the same at 1 N and
at 15 N. Contact, which the engine world and the sandbox both show as a spring that rises
tens of drags per second, keeps the thesis's AND rule on the ratio and its rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "DragSettings",
    "DragTracker",
    "DragTrackerState",
    "Rule",
    "alarm_onsets",
    "probabilities_row",
]

#: Ratios are clipped here before the log, so that a zero or negative filtered force (the
#: filter's undershoot) gives a finite, very negative log-ratio.
_MIN_RATIO = 1e-6
_MAX_RATIO = 1e12
_MAX_LOGIT = 1e6


@dataclass(frozen=True)
class DragSettings:
    """How the drag is estimated and the CUSUM accumulates (the config's fields)."""

    settle_window_s: float
    settle_fraction: float
    warmup_min_s: float
    warmup_max_s: float
    tracking_time_s: float
    min_drag: float
    max_dt_s: float
    drift: float


@dataclass(frozen=True)
class Rule:
    """The thresholds and softness scales the probabilities are made from."""

    cusum_threshold: float
    cusum_scale: float
    contact_ratio: float
    contact_ratio_rate: float
    ratio_scale: float
    ratio_rate_scale: float


@dataclass(frozen=True)
class DragTrackerState:
    """A copy of a :class:`DragTracker`'s state (its ``snapshot``)."""

    start_t: float | None
    last_t: float | None
    window: tuple[tuple[float, float], ...]
    drag: float | None
    cusum: float
    prior: float | None = None
    warmup_cusum: float = 0.0


def _median(values: list[float]) -> float:
    ordered = sorted(values)
    n = len(ordered)
    mid = n // 2
    return ordered[mid] if n % 2 else 0.5 * (ordered[mid - 1] + ordered[mid])


class DragTracker:
    """The movement's free drag, estimated online, and the CUSUM of ``log(f / drag)``.

    Warm-up: from the first sample on, the filtered force of the last two
    ``settle_window_s`` is kept; once ``warmup_min_s`` (and two windows) have passed and the
    last window's median exceeds the previous window's by at most ``settle_fraction`` (the
    start-up transient has settled), or at ``warmup_max_s`` in any case, the drag is the last
    window's median (floored at ``min_drag``). Armed: each sample adds ``(log(f/b) - drift)
    dt`` to the CUSUM (never below 0; ``dt`` capped at ``max_dt_s``, so a gap adds no
    evidence it did not see); while the CUSUM is 0 the drag follows the force with time
    constant ``tracking_time_s``, and it stays frozen while the CUSUM holds evidence.

    Carried drag (``end_movement``): the largest drag estimated in the earlier movements of
    a run is kept as a prior. During the next movement's warm-up the CUSUM then runs on
    ``log(f / prior)`` and contact is judged against the prior, so a movement that starts
    next to an object (phase 2 starts them there) is not blind until its own drag is known:
    a force that climbs past every free drag seen so far is not free sand.
    """

    def __init__(self, settings: DragSettings) -> None:
        self.settings = settings
        self._alpha_per_s = 1.0 / settings.tracking_time_s
        self._prior: float | None = None
        self.reset()

    def reset(self) -> None:
        """Start a movement afresh (the carried prior is kept; :meth:`forget` drops it)."""
        self._start_t: float | None = None
        self._last_t: float | None = None
        self._window: list[tuple[float, float]] = []
        self._drag: float | None = None
        self._cusum = 0.0
        self._warmup_cusum = 0.0

    def forget(self) -> None:
        """Start a run afresh: the movement's state and the carried prior."""
        self._prior = None
        self.reset()

    def end_movement(self) -> None:
        """Carry this movement's drag (when it was estimated) into the prior, then reset."""
        if self._drag is not None:
            self._prior = self._drag if self._prior is None else max(self._prior, self._drag)
        self.reset()

    @property
    def prior(self) -> float | None:
        """The largest drag of the earlier movements (None before any was estimated)."""
        return self._prior

    @property
    def drag(self) -> float | None:
        """The current drag estimate (None during the warm-up)."""
        return self._drag

    def snapshot(self) -> DragTrackerState:
        return DragTrackerState(self._start_t, self._last_t, tuple(self._window), self._drag,
                                self._cusum, self._prior, self._warmup_cusum)

    def restore(self, state: DragTrackerState) -> None:
        self._start_t, self._last_t = state.start_t, state.last_t
        self._window = list(state.window)
        self._drag, self._cusum = state.drag, state.cusum
        self._prior, self._warmup_cusum = state.prior, state.warmup_cusum

    def step(self, t: float, force: float, rate: float) -> tuple[bool, float, float, float]:
        """One filtered sample: (armed, ratio f/b, ratio rate f'/b in 1/s, CUSUM).

        Before the drag is estimated (not armed) the CUSUM is 0 and the ratio and its rate
        are against the median of the last ``settle_window_s`` once two have passed (1 and
        0 before); with a carried prior, the ratio, its rate and a CUSUM are against the
        prior instead, and the result counts as armed.
        ``force`` and ``rate`` must be finite (the classifier holds the last valid sample).
        """
        s = self.settings
        if self._start_t is None:
            self._start_t = t
        if self._drag is None:
            last = t if self._last_t is None else self._last_t
            provisional = self._warm_up(t, force)
            self._last_t = t
            if self._prior is not None:
                dt = min(max(t - last, 0.0), s.max_dt_s)
                ratio = min(max(force / self._prior, _MIN_RATIO), _MAX_RATIO)
                self._warmup_cusum = max(0.0, self._warmup_cusum
                                         + (math.log(ratio) - s.drift) * dt)
                return True, ratio, rate / self._prior, self._warmup_cusum
            if provisional is None:
                return False, 1.0, 0.0, 0.0
            # Contact is still caught in the warm-up, against the last window's median (a
            # movement may start next to an object); jamming is not.
            ratio = min(max(force / provisional, _MIN_RATIO), _MAX_RATIO)
            return False, ratio, rate / provisional, 0.0
        last = t if self._last_t is None else self._last_t
        dt = min(max(t - last, 0.0), s.max_dt_s)
        self._last_t = t
        drag = self._drag
        ratio = min(max(force / drag, _MIN_RATIO), _MAX_RATIO)
        cusum = max(0.0, self._cusum + (math.log(ratio) - s.drift) * dt)
        self._cusum = cusum
        if cusum == 0.0:
            # No evidence of jamming: the drag follows slow changes (a depth or a sand
            # that changes along the line, the rest of the start-up).
            weight = 1.0 - math.exp(-dt * self._alpha_per_s)
            self._drag = max(drag + weight * (force - drag), s.min_drag)
        return True, ratio, rate / drag, cusum

    def _warm_up(self, t: float, force: float) -> float | None:
        """Keep the sample; arm when the start-up has settled. Returns the provisional drag
        (the last window's median, floored) once two windows have passed, else None."""
        s = self.settings
        window = self._window
        window.append((t, force))
        span = 2.0 * s.settle_window_s
        while window and window[0][0] < t - span:
            window.pop(0)
        assert self._start_t is not None
        elapsed = t - self._start_t
        last = [f for (ti, f) in window if ti > t - s.settle_window_s]
        # Two windows in: a start-up ramp from rest is then at most 4/3 of the last
        # window's median, so only a force that jumps reads as contact.
        provisional = (max(_median(last), s.min_drag)
                       if elapsed >= span and last else None)
        if elapsed >= s.warmup_max_s:
            self._arm(last)
            return provisional
        if elapsed < max(s.warmup_min_s, span):
            return provisional
        before = [f for (ti, f) in window if ti <= t - s.settle_window_s]
        if before and last:
            previous, current = _median(before), _median(last)
            if current <= previous + s.settle_fraction * abs(previous):
                self._arm(last)
        return provisional

    def _arm(self, last: list[float]) -> None:
        self._drag = max(_median(last), self.settings.min_drag) if last else self.settings.min_drag
        self._window = []
        self._cusum = 0.0


def probabilities_row(
    armed: bool, ratio: float, ratio_rate: float, cusum: float, rule: Rule
) -> tuple[float, float, float]:
    """Probabilities of free, jamming and contact for one sample.

    Logits ``(0, m_j, m_c + max(m_j, 0))`` as in the force-rate classifier, with
    ``m_j = (S - h) / scale`` and ``m_c`` the smaller scaled margin of ratio and ratio rate
    over the contact thresholds; the arg-max is contact when ``m_c > 0``, else jamming when
    ``S > h``, else free. Not armed (warm-up): no jamming (the CUSUM counts as 0), contact
    by the ratios the tracker gave.
    """
    if not armed:
        cusum = 0.0
    m_j = (cusum - rule.cusum_threshold) / rule.cusum_scale
    m_c = min((ratio - rule.contact_ratio) / rule.ratio_scale,
              (ratio_rate - rule.contact_ratio_rate) / rule.ratio_rate_scale)
    jam = min(max(m_j, -_MAX_LOGIT), _MAX_LOGIT)
    contact = min(max(m_c + max(m_j, 0.0), -_MAX_LOGIT), _MAX_LOGIT)
    top = max(0.0, jam, contact)
    w0, w1, w2 = math.exp(-top), math.exp(jam - top), math.exp(contact - top)
    total = w0 + w1 + w2
    return w0 / total, w1 / total, w2 / total


def alarm_onsets(flagged: NDArray[np.bool_], counted: NDArray[np.bool_]) -> int:
    """How many samples start an alarm (flagged, the previous one not) where ``counted``."""
    f = np.asarray(flagged, dtype=bool)
    if f.size == 0:
        return 0
    rising = f & ~np.concatenate([[False], f[:-1]])
    return int(np.sum(rising & np.asarray(counted, dtype=bool)))
