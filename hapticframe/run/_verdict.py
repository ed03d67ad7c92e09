"""Whether a finished run's figures are a result: a run whose sensors delivered (almost)
nothing, one with a stream out of step with the robot's time, or whose every movement a
safety check halted, ran to its end but found nothing
worth reading. Its files are kept for inspection, ``run.json`` says ``status: failed`` with
the reason, and the command exits 1 (:class:`RunInconclusive`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from hapticframe._errors import RunError
from hapticframe.run._clock_check import STREAM_OUT_OF_STEP
from hapticframe.run._safety import FORCE_LIMIT, FORCE_STREAM_STALLED, OUTSIDE_WORKSPACE
from hapticframe.run._session import Session

__all__ = ["MIN_DELIVERED_FRACTION", "RunInconclusive", "inconclusive_reasons"]

#: A streamed sensor that delivered less than this share of the samples its nominal rate
#: promises over the run's model time delivered "almost nothing".
MIN_DELIVERED_FRACTION = 0.1
#: Below this many expected samples a run is too short to judge a sensor's delivery.
_MIN_EXPECTED = 20
#: The halts of the run loop's safety checks (a planner's own stop, such as an
#: ``interaction``, is the search working, not a halt of this kind).
SAFETY_HALTS = frozenset({FORCE_LIMIT, FORCE_STREAM_STALLED, OUTSIDE_WORKSPACE,
                          STREAM_OUT_OF_STEP})


class RunInconclusive(RunError):
    """The run ended, but its figures are no result (see :func:`inconclusive_reasons`).

    Attributes
    ----------
    reasons : tuple of str
        Why, one sentence each.
    metrics : dict
        What ``metrics.json`` holds (written, as every other file of the run).
    """

    def __init__(self, reasons: list[str], metrics: Mapping[str, Any]) -> None:
        super().__init__("the run is no result: " + "; ".join(reasons))
        self.reasons = tuple(reasons)
        self.metrics = dict(metrics)


def _span_s(arrays: Mapping[str, np.ndarray]) -> float:
    """The run's model time: from the first to the last time stamp of any stream."""
    first, last = math.inf, -math.inf
    for key, values in arrays.items():
        if key.endswith("/timestamps_s") and values.size:
            finite = values[np.isfinite(values)]
            if finite.size:
                first, last = min(first, float(finite.min())), max(last, float(finite.max()))
    return last - first if last > first else 0.0


def _delivery(session: Session, arrays: Mapping[str, np.ndarray]) -> list[str]:
    streamed = [cid for cid in session.components.sensors
                if cid not in session.training_sensors]
    if not streamed:
        return []
    counts = {cid: int(arrays.get(f"sensor/{cid}/timestamps_s", np.empty(0)).size)
              for cid in streamed}
    if not any(counts.values()):
        names = ", ".join(repr(c) for c in streamed)
        return [f"no sensor delivered a sample (streamed: {names})"]
    span = _span_s(arrays)
    reasons = []
    for cid, count in counts.items():
        rates = [info.rate_hz for info in session.components.sensors[cid].channels.values()
                 if math.isfinite(info.rate_hz) and info.rate_hz > 0]
        if not rates:
            continue  # no nominal rate: nothing to hold its delivery against
        rate = max(rates)
        expected = span * rate
        if expected >= _MIN_EXPECTED and count < MIN_DELIVERED_FRACTION * expected:
            reasons.append(f"sensor {cid!r} delivered {count} samples where its {rate:g} Hz "
                           f"rate promises about {expected:.0f} over {span:.2f} s of model "
                           "time (its device counters are in metrics.json)")
    return reasons


def _halts(session: Session) -> list[str]:
    movements = session.movements
    if not movements or not all(m.halted and m.halt_reason in SAFETY_HALTS
                                for m in movements):
        return []
    reasons = sorted({m.halt_reason for m in movements})
    return [f"every movement ({len(movements)}) was halted by a safety check "
            f"({', '.join(reasons)}; run.json: details.safety_halts)"]


def inconclusive_reasons(session: Session) -> list[str]:
    """Why the finished run's figures are no result (empty: they are one)."""
    arrays = session.recorder.arrays()
    return (_out_of_step(session) + _limit(session) + _delivery(session, arrays)
            + _halts(session))


def _limit(session: Session) -> list[str]:
    limit = session.details.get("limit")
    return [str(limit["reason"])] if limit else []


def _out_of_step(session: Session) -> list[str]:
    fault = session.details.get("out_of_step")
    return [str(fault["detail"])] if fault else []
