"""Per-device health counters, written to metrics.json and shown in the progress line."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from hapticframe.devices._framing import ParserStats

__all__ = ["DeviceHealth"]

_PARSER_FIELDS = ("bytes", "frames", "crc_errors", "resyncs", "overflows")


@dataclass
class DeviceHealth:
    """Counters of what a device did and what went wrong.

    Attributes
    ----------
    bytes, frames : int
        Bytes received and valid frames parsed.
    crc_errors, resyncs : int
        Frames that failed their check, and bytes skipped to find the next frame.
    timeouts : int
        Replies or stream data that did not come in time (a watchdog fired).
    stalls : int
        Periods without data that were long enough to count.
    reconnects : int
        Times the link was reopened.
    dropped_samples : int
        Samples the device should have sent and did not (gaps in a sequence or clock).
    invalid_samples : int
        Samples delivered marked invalid (out of range, a bad status).
    recoveries : int
        Recovery attempts (see :meth:`DeviceLifecycle.recover`).
    overflows : int
        Times received data were dropped because a buffer limit was reached.
    late_samples : int
        Samples that arrived later after their stamp than the device allows (a networked
        source: a ROS 2 topic).
    out_of_order : int
        Samples whose stamp was not after the last delivered one (dropped, never delivered).
    """

    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    resyncs: int = 0
    timeouts: int = 0
    stalls: int = 0
    reconnects: int = 0
    dropped_samples: int = 0
    invalid_samples: int = 0
    recoveries: int = 0
    overflows: int = 0
    late_samples: int = 0
    out_of_order: int = 0
    _seen: dict[int, ParserStats] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def as_dict(self) -> dict[str, int]:
        """Every counter by name."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.init}

    def faults(self) -> dict[str, int]:
        """The non-zero counters other than bytes and frames (what the progress line shows)."""
        return {
            name: value
            for name, value in self.as_dict().items()
            if value and name not in ("bytes", "frames")
        }

    def add_parser(self, stats: ParserStats) -> None:
        """Add what ``stats`` counted since the previous call with the same parser.

        A parser whose counters went down (it was replaced or reset) counts from zero.
        """
        previous = self._seen.get(id(stats))
        current = ParserStats(**asdict(stats))
        if previous is None or any(
            getattr(current, name) < getattr(previous, name) for name in _PARSER_FIELDS
        ):
            previous = ParserStats()
        for name in _PARSER_FIELDS:
            delta = getattr(current, name) - getattr(previous, name)
            setattr(self, name, getattr(self, name) + delta)
        self._seen[id(stats)] = current
