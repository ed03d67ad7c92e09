"""Declarative, seeded fault schedules for device emulators.

A schedule is a list of :class:`FaultEvent` (one-shot at a time, or random at a rate). The
emulator harness asks it about byte-level faults; each device model asks it about its own
protocol faults. Everything random comes from the generator passed in, so a seed replays a
run's faults exactly.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    GetCoreSchemaHandler,
    Tag,
    field_validator,
    model_validator,
)

__all__ = [
    "BYTE_FAULT_KINDS",
    "MAX_FAULT_RATE_HZ",
    "MAX_FAULT_TIME_S",
    "FaultEvent",
    "FaultKind",
    "FaultKinds",
    "FaultParam",
    "FaultSchedule",
    "FaultSetting",
    "FaultValue",
    "InjectedFault",
    "fault_setting",
]

#: The highest mean rate of a random fault: one a millisecond. Occurrences are generated
#: up to the time asked, so an unbounded rate grows memory without bound.
MAX_FAULT_RATE_HZ = 1000.0
#: The latest ``at_s`` and the longest ``duration_s`` of a fault: about 11.6 days.
MAX_FAULT_TIME_S = 1e6


@dataclass(frozen=True)
class FaultParam:
    """One parameter of a fault kind: a number in ``[low, high]`` (an integer when
    ``integer``), or one of ``choices`` when those are given."""

    low: float = 0.0
    high: float = 0.0
    integer: bool = False
    choices: tuple[str, ...] = ()

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused, or None."""
        if self.choices:
            if value not in self.choices:
                return f"must be one of {', '.join(map(repr, self.choices))}, got {value!r}"
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            return f"must be a number, got {value!r}"
        if self.integer and not isinstance(value, int):
            return f"must be an integer, got {value!r}"
        if not (math.isfinite(value) and self.low <= value <= self.high):
            return f"must lie in [{self.low:g}, {self.high:g}], got {value!r}"
        return None


@dataclass(frozen=True)
class FaultKind:
    """One kind of fault an emulator applies: what it does and the parameters it reads.

    A device's config declares its kinds (``faults: fault_setting(KINDS)``), so that
    ``validate`` refuses a misspelt kind, one the device does not have, and a parameter
    the emulator does not read or cannot take.
    """

    description: str
    params: Mapping[str, FaultParam] = field(default_factory=dict, hash=False)


#: The faults the emulator harness applies to the device→host byte stream.
BYTE_FAULT_KINDS: Mapping[str, FaultKind] = {
    "drop_bytes": FaultKind("params.count bytes (default 1) lost from the stream",
                            {"count": FaultParam(1, 65536, integer=True)}),
    "garbage": FaultKind("params.count random bytes (default 1) inserted into the stream",
                         {"count": FaultParam(1, 65536, integer=True)}),
    "fragment": FaultKind("the stream delivered a byte at a time, for duration_s"),
    "stall": FaultKind("nothing delivered for duration_s; params.drop=1 loses what the "
                       "device sent meanwhile", {"drop": FaultParam(0, 1, integer=True)}),
    "disconnect": FaultKind("the port goes away (for duration_s) and comes back"),
}
BYTE_FAULTS = tuple(BYTE_FAULT_KINDS)


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
        if self.rate_hz is not None and not 0 < self.rate_hz <= MAX_FAULT_RATE_HZ:
            raise ValueError(f"fault {self.kind!r}: rate_hz must be positive and at most "
                             f"{MAX_FAULT_RATE_HZ:g}, got {self.rate_hz!r}")
        if self.at_s is not None and not 0 <= self.at_s <= MAX_FAULT_TIME_S:
            raise ValueError(f"fault {self.kind!r}: at_s must lie in [0, {MAX_FAULT_TIME_S:g}] "
                             f"s, got {self.at_s!r}")
        if not 0 <= self.duration_s <= MAX_FAULT_TIME_S:
            raise ValueError(f"fault {self.kind!r}: duration_s must lie in "
                             f"[0, {MAX_FAULT_TIME_S:g}] s, got {self.duration_s!r}")
        for name, value in self.params.items():
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"fault {self.kind!r}: params.{name} must be finite")


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


class _FaultEntry(BaseModel):
    """One entry of a ``faults`` list, as experiment files write it."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    #: The kinds an entry may name (each device's subclass sets its own).
    allowed_kinds: ClassVar[Mapping[str, FaultKind]] = BYTE_FAULT_KINDS

    kind: str = Field(description="The fault's kind: one the device's emulator applies.")
    at_s: float | None = Field(
        None, ge=0, le=MAX_FAULT_TIME_S, strict=False,
        description="One occurrence at this device time (s) ...",
    )
    rate_hz: float | None = Field(
        None, gt=0, le=MAX_FAULT_RATE_HZ,
        description="... or random occurrences (a Poisson process) at this mean rate.",
    )
    duration_s: float = Field(
        0.0, ge=0, le=MAX_FAULT_TIME_S, description="How long an occurrence lasts (s)."
    )
    params: dict[str, float | int | str] = Field(
        default_factory=dict, description="The kind's parameters (see the device's kinds)."
    )

    @model_validator(mode="before")
    @classmethod
    def _a_mapping(cls, value: Any) -> Any:
        if not isinstance(value, Mapping):
            raise ValueError(f"a fault is a mapping with at least a 'kind', got {value!r}")
        return value

    @field_validator("at_s", "rate_hz", "duration_s", mode="before")
    @classmethod
    def _numbers(cls, value: Any) -> Any:
        if isinstance(value, bool):
            raise ValueError(f"must be a number, not {value!r}")
        return value

    @field_validator("kind")
    @classmethod
    def _known_kind(cls, value: str) -> str:
        kinds = cls.allowed_kinds
        if value not in kinds:
            close = difflib.get_close_matches(value, list(kinds), n=3, cutoff=0.6)
            hint = (f"; did you mean {' or '.join(map(repr, close))}?" if close
                    else f"; its kinds are {', '.join(sorted(kinds))}")
            raise ValueError(f"this device has no fault kind {value!r}{hint}")
        return value

    @model_validator(mode="after")
    def _timing_and_params(self) -> _FaultEntry:
        if (self.at_s is None) == (self.rate_hz is None):
            raise ValueError("give exactly one of at_s and rate_hz (one occurrence at a time, "
                             "or random ones at a mean rate)")
        kinds = self.allowed_kinds
        declared = kinds[self.kind].params
        for name, value in self.params.items():
            spec = declared.get(name)
            if spec is None:
                known = ", ".join(sorted(declared)) or "none"
                raise ValueError(f"params.{name}: fault kind {self.kind!r} reads no parameter "
                                 f"{name!r} (its parameters: {known})")
            problem = spec.problem(value)
            if problem is not None:
                raise ValueError(f"params.{name} of fault kind {self.kind!r} {problem}")
        return self

    def entry(self) -> dict[str, Any]:
        """The plain mapping :meth:`FaultSchedule.from_config` reads."""
        out: dict[str, Any] = {"kind": self.kind}
        if self.at_s is not None:
            out["at_s"] = self.at_s
        if self.rate_hz is not None:
            out["rate_hz"] = self.rate_hz
        if self.duration_s:
            out["duration_s"] = self.duration_s
        if self.params:
            out["params"] = dict(self.params)
        return out


def _entries(value: tuple[_FaultEntry, ...] | str) -> Any:
    return value if isinstance(value, str) else tuple(item.entry() for item in value)


def _setting_tag(value: Any) -> str:
    return "name" if isinstance(value, str) else "list"


def _as_tuple(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def fault_setting(kinds: Mapping[str, FaultKind], *, byte_faults: bool = True) -> Any:
    """The type of an emulated device's ``faults`` setting: ``"none"``, ``"standard"`` (the
    device's own schedule) or a list of entries ``{kind, at_s | rate_hz, duration_s,
    params}`` whose kinds are ``kinds`` (and the harness's :data:`BYTE_FAULT_KINDS` unless
    ``byte_faults`` is false: a device not behind the byte harness).

    Each entry is checked where it is written (``faults[2].rate_hz``, ``faults[0].kind``):
    a kind the device lacks (with the closest names), a time that is not finite, a rate
    above :data:`MAX_FAULT_RATE_HZ`, a parameter the kind does not read or outside its
    range. The validated value holds plain mappings, as :meth:`FaultSchedule.from_config`
    reads them.
    """
    allowed = {**(BYTE_FAULT_KINDS if byte_faults else {}), **kinds}
    names = ", ".join(sorted(allowed))
    entry = type("FaultEntry", (_FaultEntry,), {
        "__doc__": f"One fault of this device's emulator; kinds: {names}.",
        "allowed_kinds": allowed,
    })
    # Tagged by the value's type, so that a bad list is reported entry by entry and not
    # also as "not 'none' or 'standard'".
    named: Any = Annotated[Literal["none", "standard"], Tag("name")]
    listed: Any = Annotated[tuple[entry, ...], Tag("list")]  # type: ignore[valid-type]
    setting: Any = Annotated[named | listed, Discriminator(_setting_tag)]
    return Annotated[setting, BeforeValidator(_as_tuple), AfterValidator(_entries)]


#: What a validated ``faults`` setting holds: a schedule's name, or plain entries.
FaultValue = Literal["none", "standard"] | tuple[dict[str, Any], ...]


@dataclass(frozen=True, eq=False)
class FaultKinds:
    """Marks a ``faults`` field with the kinds its device's emulator applies::

        faults: Annotated[FaultValue, FaultKinds(FAULT_KINDS)] = Field("none", ...)

    validates as :func:`fault_setting` (``byte_faults=False`` for a device not behind the
    byte harness), and reads as a plain annotation to a type checker.
    """

    kinds: Mapping[str, FaultKind]
    byte_faults: bool = True

    def __get_pydantic_core_schema__(self, source: Any, handler: GetCoreSchemaHandler) -> Any:
        return handler.generate_schema(fault_setting(self.kinds, byte_faults=self.byte_faults))


#: The ``faults`` setting of an emulated device with only the harness's byte-level faults
#: (:data:`BYTE_FAULT_KINDS`); a device with kinds of its own uses :class:`FaultKinds`.
FaultSetting = Annotated[FaultValue, FaultKinds({})]
