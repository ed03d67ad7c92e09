"""The FT 300 stream's own clock: frame numbers, their host times, and the frames missing.

The sensor sends a frame every 10 ms on its own crystal and numbers none of them. The host
only sees when a read found them, and a read finds frames late and in bursts whenever the
host is busy. Each frame is therefore numbered on the stream's 100 Hz sequence and
:class:`~hapticframe.devices.ClockSync` maps the numbers onto host time through the promptest
receipts. A frame is counted missing only on evidence that holds for the sequence, not for
one receipt:

- a frame that failed its CRC before a valid one is a *hint* that one slot was lost; the
  hint stands unless the next frame then arrives before its slot could have been sent (a
  candidate made of garbage bytes, not a lost frame), which would be impossible;
- frames found late are late, not a sign of lost ones, unless the link had fallen silent
  before them (frames lost on the line leave it quiet; a backlog keeps it busy) and the
  lateness then persists: after :data:`CONFIRM_READS` reads in a row whose frames are all
  at least :data:`LATE_FRACTION` of a period behind their slots, the sequence has really
  moved on, and the slots it skipped are counted. A host that reads late (a loaded machine,
  a slow adapter delivering a backlog in one burst) makes late reads now and then, which
  the next prompt one ends;
- when a stream ends (the link failed, the frame watchdog fired), the driver counts the
  stream's frames that still arrive while it is silenced and are discarded; the time the
  restart takes is not counted (no stream runs then), nor the silence of a stream that
  stopped (the host cannot tell frames lost on the line from frames never sent).

Frames that came after lost ones were dated a period early until the count (the frames of
:data:`CONFIRM_READS` reads at most); that is the price of never counting a late frame
as lost.
"""

from __future__ import annotations

import math

from hapticframe.devices import ClockSync

__all__ = ["CONFIRM_READS", "LATE_FRACTION", "StreamNumbering"]

#: Reads in a row whose frames must all be late before the skipped slots are counted.
CONFIRM_READS = 10
#: How late (in periods) a read's promptest frame must be to count towards that run.
LATE_FRACTION = 0.75


class StreamNumbering:
    """Numbers one stream's frames, dates them, and counts the missing ones.

    Parameters
    ----------
    period_s : float
        The stream's nominal period.
    """

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        # No drift fit: over its one-second window a crystal's drift is a few microseconds,
        # while a slope fitted to jittery receipts would swing the mapping by milliseconds.
        self._sync = ClockSync(period_s, window=100, max_drift=0.0)
        self._seq: int | None = None
        self._late_run = 0
        self._late_min = math.inf
        #: Frames missing from the sequences numbered so far.
        self.missing = 0

    @property
    def started(self) -> bool:
        """Whether the current stream has delivered a frame."""
        return self._seq is not None

    def restart(self) -> None:
        """A new stream: its frames count from zero again."""
        self._sync.reset()
        self._seq = None
        self._late_run, self._late_min = 0, math.inf

    def times(
        self, n: int, now_s: float, rejected: int = 0, silent_s: float = 0.0
    ) -> list[float]:
        """Host times of ``n`` frames one read found at ``now_s``; ``rejected``: frames that
        failed their CRC just before the first of them; ``silent_s``: how long the link had
        been silent before them."""
        if n <= 0:
            return []
        period = self.period_s
        sync = self._sync
        # Frames found together were sent one period apart: date them back from now. They
        # are one observation of lateness, whatever their number.
        receipts = [now_s - (n - 1 - k) * period for k in range(n)]
        if self._seq is None:
            first = 0
        else:
            first = self._seq + 1 + rejected
            late = receipts[0] - sync.host_time(first * period)
            if late < -0.5 * period:  # before its slot: fewer were lost than hinted
                first = max(self._seq + 1, first - round(-late / period))
            late = min(receipt - sync.host_time((first + k) * period)
                       for k, receipt in enumerate(receipts))
            first += self._confirmed_skip(late, silent_s >= 1.5 * period)
            self.missing += first - self._seq - 1
        numbers = [first + k for k in range(n)]
        for number, receipt in zip(numbers, receipts, strict=True):
            sync.update(number * period, receipt)
        self._seq = numbers[-1]
        return [sync.host_time(number * period) for number in numbers]

    def _confirmed_skip(self, late_s: float, after_silence: bool) -> int:
        """Slots skipped, once a run of late reads that began after a silent link shows
        that the sequence moved on (a backlog keeps the link busy, a loss leaves it quiet)."""
        period = self.period_s
        if late_s < LATE_FRACTION * period or (self._late_run == 0 and not after_silence):
            self._late_run, self._late_min = 0, math.inf
            return 0
        self._late_run += 1
        self._late_min = min(self._late_min, late_s)
        if self._late_run < CONFIRM_READS:
            return 0
        skipped = max(1, round(self._late_min / period))
        self._late_run, self._late_min = 0, math.inf
        return skipped
