"""Declarative, seeded fault schedules for device emulators.

A schedule is a list of :class:`FaultEvent` (one-shot at a time, or random at a rate). The
emulator harness asks it about byte-level faults; each device model asks it about its own
protocol faults. Everything random comes from the generator passed in, so a seed replays a
run's faults exactly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator

__all__ = ["FaultEvent", "FaultSchedule", "FaultSetting", "InjectedFault"]

#: The faults the emulator harness applies to the device→host byte stream.
BYTE_FAULTS = ("drop_bytes", "garbage", "fragment", "stall", "disconnect")


@dataclass(frozen=True)
class FaultEvent:
    """One fault: when it happens, how long it lasts, and its parameters.

    Parameters
    ----------
    kind : str
        ``"drop_bytes"``, ``"garbage"``, ``"fragment"``, ``"stall"``, ``"disconnect"`` (applied
        by the harness), or a device model's own kind (``"bad_crc"``, ``"out_of_range"``...).
    at_s : float or None
        A single occurrence at this device time ...
    rate_hz : float or None
        ... or random occurrences (a Poisson process) at this mean rate, from the time the
        schedule is first asked. Exactly one of the two is given.
    duration_s : float
        How long an occurrence lasts (stall, disconnect, out_of_range); 0 = instantaneous.
    params : mapping
        Kind-specific settings, e.g. ``{"count": 3}``.
    """

    kind: str
    at_s: float | None = None
    rate_hz: float | None = None
    duration_s: float = 0.0
    params: Mapping[str, float | int | str] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        if not self.kind:
            raise ValueError("a fault needs a kind")
        if (self.at_s is None) == (self.rate_hz is None):
            raise ValueError(f"fault {self.kind!r}: give exactly one of at_s and rate_hz")
        if self.rate_hz is not None and not self.rate_hz > 0:
            raise ValueError(f"fault {self.kind!r}: rate_hz must be positive")
        if not self.duration_s >= 0:
            raise ValueError(f"fault {self.kind!r}: duration_s must be non-negative")


@dataclass(frozen=True)
class InjectedFault:
    """A record of one fault occurrence that was applied."""

    kind: str
    time_s: float
    detail: str


class _Occurrences:
    """The occurrence times of one event, generated lazily and in order."""

    def __init__(self, event: FaultEvent, rng: np.random.Generator) -> None:
        self.event = event
        self.rng = rng
        self.pending: list[float] = []  # generated, not yet taken, in order
        self.taken: list[float] = []  # taken, kept while they may still be active
        self.next_s: float | None = event.at_s
        self.started = event.at_s is not None

    def generate(self, now_s: float) -> None:
        event = self.event
        if not self.started:  # a rate starts when the schedule is first asked
            self.started = True
            assert event.rate_hz is not None
            self.next_s = now_s + float(self.rng.exponential(1.0 / event.rate_hz))
        while self.next_s is not None and self.next_s <= now_s:
            self.pending.append(self.next_s)
            if event.rate_hz is None:
                self.next_s = None
            else:
                self.next_s += float(self.rng.exponential(1.0 / event.rate_hz))


class FaultSchedule:
    """When each fault happens, deterministic for a given generator.

    Parameters
    ----------
    events : sequence of FaultEvent
    rng : numpy.random.Generator
        Seeds one generator per event (so one event's occurrences do not depend on how often
        another is asked about) and the byte-level choices (:attr:`rng`).

    Attributes
    ----------
    injected : list of InjectedFault
        What fired, in order.
    rng : numpy.random.Generator
        For the random content of faults (positions, garbage bytes, fragment sizes).
    """

    def __init__(self, events: Sequence[FaultEvent], rng: np.random.Generator) -> None:
        self.events = tuple(events)
        seeds = rng.integers(0, 2**63, size=len(self.events) + 1)
        self._occurrences = [
            _Occurrences(event, np.random.default_rng(int(seed)))
            for event, seed in zip(self.events, seeds[:-1], strict=True)
        ]
        self.rng = np.random.default_rng(int(seeds[-1]))
        self.injected: list[InjectedFault] = []

    @classmethod
    def from_config(
        cls, entries: Sequence[Mapping[str, Any]], rng: np.random.Generator
    ) -> FaultSchedule:
        """A schedule from plain dicts (YAML): keys ``kind``, ``at_s``, ``rate_hz``,
        ``duration_s``, ``params``.

        Raises
        ------
        ValueError
            For an unknown key, a missing kind, or an invalid event.
        """
        allowed = {"kind", "at_s", "rate_hz", "duration_s", "params"}
        events = []
        for number, entry in enumerate(entries):
            unknown = sorted(set(entry) - allowed)
            if unknown:
                raise ValueError(
                    f"fault {number}: unknown key(s) {', '.join(unknown)} "
                    f"(allowed: {', '.join(sorted(allowed))})"
                )
            if "kind" not in entry:
                raise ValueError(f"fault {number}: 'kind' is required")
            params = entry.get("params", {})
            if not isinstance(params, Mapping):
                raise ValueError(f"fault {number}: 'params' must be a mapping")
            events.append(
                FaultEvent(
                    kind=str(entry["kind"]),
                    at_s=None if entry.get("at_s") is None else float(entry["at_s"]),
                    rate_hz=None if entry.get("rate_hz") is None else float(entry["rate_hz"]),
                    duration_s=float(entry.get("duration_s", 0.0)),
                    params=dict(params),
                )
            )
        return cls(events, rng)

    @property
    def kinds(self) -> frozenset[str]:
        """The kinds this schedule can inject."""
        return frozenset(event.kind for event in self.events)

    def _log(self, event: FaultEvent, time_s: float) -> None:
        parts = [f"{key}={value}" for key, value in sorted(event.params.items())]
        if event.duration_s:
            parts.insert(0, f"for {event.duration_s:g} s")
        self.injected.append(InjectedFault(event.kind, time_s, " ".join(parts)))

    def fires(self, kind: str, now_s: float) -> FaultEvent | None:
        """An occurrence of ``kind`` due at or before ``now_s``, each returned only once.

        Several due occurrences are returned one per call (earliest first).
        """
        best: tuple[float, _Occurrences] | None = None
        for occ in self._occurrences:
            if occ.event.kind != kind:
                continue
            occ.generate(now_s)
            if occ.pending and (best is None or occ.pending[0] < best[0]):
                best = (occ.pending[0], occ)
        if best is None:
            return None
        time_s, occ = best
        occ.pending.pop(0)
        self._remember(occ, time_s, now_s)
        self._log(occ.event, time_s)
        return occ.event

    def active(self, kind: str, now_s: float) -> FaultEvent | None:
        """An occurrence of ``kind`` whose interval ``[t, t + duration_s)`` holds ``now_s``.

        An occurrence is logged the first time it is seen, by this or :meth:`fires`.
        """
        found: FaultEvent | None = None
        for occ in self._occurrences:
            if occ.event.kind != kind:
                continue
            occ.generate(now_s)
            while occ.pending:  # newly due: taken (and logged) now
                time_s = occ.pending.pop(0)
                self._remember(occ, time_s, now_s)
                self._log(occ.event, time_s)
            duration = occ.event.duration_s
            occ.taken = [t for t in occ.taken if t + duration > now_s]
            if found is None and any(t <= now_s < t + duration for t in occ.taken):
                found = occ.event
        return found

    @staticmethod
    def _remember(occ: _Occurrences, time_s: float, now_s: float) -> None:
        occ.taken.append(time_s)
        # Occurrences that have ended can never be active again.
        occ.taken = [t for t in occ.taken if t + occ.event.duration_s > now_s]

    def count(self, kind: str) -> int:
        """How many occurrences of ``kind`` have been injected."""
        return sum(1 for fault in self.injected if fault.kind == kind)


def _checked_fault_setting(value: Any) -> Any:
    """A list of fault entries checked as :meth:`FaultSchedule.from_config` will check them
    at run time, so that ``hapticframe validate`` reports a bad entry with its location."""
    if isinstance(value, list):
        value = tuple(value)
    if isinstance(value, tuple):
        for number, entry in enumerate(value):
            if not isinstance(entry, Mapping):
                raise ValueError(f"fault {number}: a mapping with at least a 'kind', got {entry!r}")
        FaultSchedule.from_config(value, np.random.default_rng(0))
        value = tuple(dict(entry) for entry in value)
    return value


#: The ``faults`` setting of an emulated device's config: ``"none"``, ``"standard"`` (the
#: device's own schedule) or a list of entries ``{kind, at_s | rate_hz, duration_s, params}``.
FaultSetting = Annotated[
    Literal["none", "standard"] | tuple[dict[str, Any], ...],
    BeforeValidator(_checked_fault_setting),
]
